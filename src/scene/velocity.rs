//! Initial velocity of a body as a field of the reference position X (`bodies[].velocity`):
//! a translation, a rigid rotation about a point and velocity profiles (a table along one axis,
//! a beam's mode shape), summed. Each particle starts with the field's value at its reference
//! position; particles of boundary groups start at rest along the held axes.
//!
//! JSON (TOML alike):
//!
//! ```json
//! "velocity": [1.0, 0.0]
//! "velocity": {
//!   "linear": [0.0, 0.0],
//!   "angular": { "omega": 2.0, "center": [0.1, 0.0] },
//!   "profiles": [
//!     { "table": { "axis": "x", "component": "y", "points": [[0.0, 0.0], [0.2, 0.01]] } },
//!     { "mode_shape": { "shape": "clamped_free_1", "axis": "x", "component": "y",
//!                       "x0": 0.0, "length": 0.2, "amplitude": 0.01 } }
//!   ]
//! }
//! ```
//!
//! The array is the original form (a uniform velocity); null or no field is rest.
use super::limits::{self, num};
use super::{axis_index, err, SceneError};
use schemars::JsonSchema;
use serde::{de, Deserialize, Deserializer, Serialize, Serializer};

/// Initial velocity of a body.
///
/// In JSON and TOML either an array `[vx, vy(, vz)]` (m/s, every particle moves with it) or an
/// object, a [`VelocityField`]. Binary formats (the bincode of FMU states) write the variant
/// explicitly, since they cannot tell an array from an object.
#[derive(Clone, Debug, PartialEq, JsonSchema)]
#[schemars(untagged)]
pub enum BodyVelocity {
    /// Every particle moves with this velocity (m/s), `dimension` components.
    Uniform(Vec<f64>),
    /// The sum of the field's parts at each particle's reference position.
    Field(VelocityField),
}

/// A velocity field: the sum of its parts, each evaluated at the reference position X (m).
/// Every part is optional; an empty object is rest.
#[derive(Clone, Debug, PartialEq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct VelocityField {
    /// Translation (m/s), `dimension` components.
    #[serde(default)]
    pub linear: Option<Vec<f64>>,
    /// Rigid rotation about a point: v = omega x (X - center).
    #[serde(default)]
    pub angular: Option<AngularVelocity>,
    /// Profiles, each adding to one velocity component.
    #[serde(default)]
    pub profiles: Vec<VelocityProfile>,
}

/// A rigid rotation: v(X) = omega x (X - center). Operators with particle rotations (the
/// paper's) also give each particle the angular velocity omega, so that a rigid spin carries
/// no shear; the corrected operator has no particle rotations.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct AngularVelocity {
    /// Angular velocity (rad/s): in 2D a number (about z, counter-clockwise positive), in 3D a
    /// vector [wx, wy, wz].
    pub omega: Omega,
    /// The point the body turns about (m), `dimension` components (reference coordinates).
    pub center: Vec<f64>,
}

/// An angular velocity (rad/s): a number in 2D, a vector of three in 3D.
#[derive(Clone, Debug, PartialEq, JsonSchema)]
#[schemars(untagged)]
pub enum Omega {
    /// About z (2D).
    Scalar(f64),
    /// [wx, wy, wz] (3D).
    Vector(Vec<f64>),
}

/// A velocity profile: one velocity component (m/s) as a function of one reference coordinate
/// (m). Externally tagged: `{"table": {...}}`, `{"mode_shape": {...}}`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum VelocityProfile {
    /// A table of the velocity component over one coordinate.
    Table(TableProfile),
    /// A beam's vibration mode.
    ModeShape(ModeShapeProfile),
}

/// A table v(s) of velocity component `component` (m/s) over the reference coordinate s along
/// `axis` (m), interpolated linearly between its points and constant beyond the first and the
/// last point.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct TableProfile {
    /// The axis s runs along: "x", "y" or "z".
    pub axis: String,
    /// The velocity component set: "x", "y" or "z".
    pub component: String,
    /// [s (m), v (m/s)] pairs, at least one, s strictly increasing.
    pub points: Vec<[f64; 2]>,
}

/// A beam's vibration mode as a velocity profile: v(X) = amplitude f(s) / f(length) along
/// `component`, with s = X[axis] - x0 taken in [0, length] (the value at the clamp behind it,
/// the tip value beyond the tip).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ModeShapeProfile {
    /// Which mode.
    pub shape: ModeShape,
    /// The beam's axis: "x", "y" or "z".
    pub axis: String,
    /// The transverse velocity component set (not the axis): "x", "y" or "z".
    pub component: String,
    /// Position of the clamp along `axis` (m).
    pub x0: f64,
    /// Length of the beam from the clamp to the free end (m), > 0.
    pub length: f64,
    /// Velocity at the free end (m/s).
    pub amplitude: f64,
}

/// Named mode shapes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
pub enum ModeShape {
    /// First bending mode of a clamped-free (cantilever) Euler-Bernoulli beam, the initial
    /// velocity of the oscillating plate of Gray, Monaghan & Swift (2001):
    /// f(s) = (cos kL + cosh kL)(cosh ks - cos ks) + (sin kL - sinh kL)(sinh ks - sin ks),
    /// kL = 1.875104. f(0) = f'(0) = 0 at the clamp, f'' = f''' = 0 at the free end.
    #[serde(rename = "clamped_free_1")]
    ClampedFree1,
}

/// kL of the first clamped-free mode as Gray, Monaghan & Swift (2001) give it (the root of
/// 1 + cos kL cosh kL = 0 is 1.8751040687...).
pub const CLAMPED_FREE_1_KL: f64 = 1.875104;

impl ModeShape {
    /// The shape at s in [0, l] over its value at l (-): 0 at the clamp, 1 at the free end.
    pub fn normalised(self, s: f64, l: f64) -> f64 {
        match self {
            ModeShape::ClampedFree1 => {
                let kl = CLAMPED_FREE_1_KL;
                let f = |s: f64| {
                    let ks = kl * s / l;
                    (kl.cos() + kl.cosh()) * (ks.cosh() - ks.cos())
                        + (kl.sin() - kl.sinh()) * (ks.sinh() - ks.sin())
                };
                f(s.clamp(0.0, l)) / f(l)
            }
        }
    }
}

impl BodyVelocity {
    /// Whether the velocity is zero everywhere by its numbers (every part zero).
    pub fn is_zero(&self) -> bool {
        let zero = |v: &[f64]| v.iter().all(|c| *c == 0.0);
        match self {
            BodyVelocity::Uniform(u) => zero(u),
            BodyVelocity::Field(f) => {
                f.linear.as_deref().is_none_or(zero)
                    && f.angular.as_ref().is_none_or(|a| match &a.omega {
                        Omega::Scalar(w) => *w == 0.0,
                        Omega::Vector(w) => zero(w),
                    })
                    && f.profiles.iter().all(|p| match p {
                        VelocityProfile::Table(t) => t.points.iter().all(|p| p[1] == 0.0),
                        VelocityProfile::ModeShape(m) => m.amplitude == 0.0,
                    })
            }
        }
    }

    /// Velocity (m/s) and angular velocity (rad/s) at the reference position `x` (m), as
    /// 3-arrays (z = 0 in 2D; the angular velocity of a 2D scene is about z).
    pub fn at(&self, x: [f64; 3]) -> ([f64; 3], [f64; 3]) {
        let mut v = [0.0; 3];
        let mut w = [0.0; 3];
        let add = |v: &mut [f64; 3], a: &[f64]| {
            for (c, a) in v.iter_mut().zip(a) {
                *c += a;
            }
        };
        match self {
            BodyVelocity::Uniform(u) => add(&mut v, u),
            BodyVelocity::Field(f) => {
                if let Some(l) = &f.linear {
                    add(&mut v, l);
                }
                if let Some(a) = &f.angular {
                    let om = match &a.omega {
                        Omega::Scalar(wz) => [0.0, 0.0, *wz],
                        Omega::Vector(o) => [o[0], o[1], o[2]],
                    };
                    let mut r = [0.0; 3];
                    for k in 0..3 {
                        r[k] = x[k] - a.center.get(k).copied().unwrap_or(0.0);
                    }
                    let c = [
                        om[1] * r[2] - om[2] * r[1],
                        om[2] * r[0] - om[0] * r[2],
                        om[0] * r[1] - om[1] * r[0],
                    ];
                    add(&mut v, &c);
                    add(&mut w, &om);
                }
                for p in &f.profiles {
                    match p {
                        VelocityProfile::Table(t) => {
                            let s = x[axis_index(&t.axis).expect("validated")];
                            v[axis_index(&t.component).expect("validated")] +=
                                table_at(&t.points, s);
                        }
                        VelocityProfile::ModeShape(m) => {
                            let s = x[axis_index(&m.axis).expect("validated")] - m.x0;
                            v[axis_index(&m.component).expect("validated")] +=
                                m.amplitude * m.shape.normalised(s, m.length);
                        }
                    }
                }
            }
        }
        (v, w)
    }
}

/// Linear interpolation in a table of (s, v) with s increasing, constant beyond its ends.
fn table_at(points: &[[f64; 2]], s: f64) -> f64 {
    let n = points.len();
    if s <= points[0][0] {
        return points[0][1];
    }
    if s >= points[n - 1][0] {
        return points[n - 1][1];
    }
    // points[k - 1][0] < s <= points[k][0]
    let k = points.partition_point(|p| p[0] < s);
    let ([s0, v0], [s1, v1]) = (points[k - 1], points[k]);
    v0 + (v1 - v0) * (s - s0) / (s1 - s0)
}

fn finite(field: &str, v: f64) -> Result<(), SceneError> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(err(
            field,
            format!("must be a finite number, got {}", num(v)),
        ))
    }
}

/// A velocity (m/s) within [`limits::SPEED`].
fn speed(field: &str, v: f64) -> Result<(), SceneError> {
    finite(field, v)?;
    limits::SPEED.check(v).map_err(|m| err(field, m))
}

/// A velocity vector: `d` components, each within [`limits::SPEED`].
fn velocities(field: &str, v: &[f64], d: usize) -> Result<(), SceneError> {
    components(field, v, d)?;
    for (k, c) in v.iter().enumerate() {
        speed(&format!("{field}[{k}]"), *c)?;
    }
    Ok(())
}

fn components(field: &str, v: &[f64], d: usize) -> Result<(), SceneError> {
    if v.len() != d {
        return Err(err(
            field,
            format!("must have {d} components, got {}", v.len()),
        ));
    }
    if let Some(x) = v.iter().find(|x| !x.is_finite()) {
        return Err(err(field, format!("component {} is not finite", num(*x))));
    }
    Ok(())
}

fn axis(field: &str, name: &str, d: usize) -> Result<usize, SceneError> {
    match axis_index(name) {
        Some(i) if i < d => Ok(i),
        _ => Err(err(
            field,
            format!(
                "'{}' is not an axis of a {d}D scene ({})",
                name.escape_debug(),
                if d == 2 { "x or y" } else { "x, y or z" }
            ),
        )),
    }
}

/// Checks a body's initial velocity; `field` is the path of the `velocity` field.
/// Checks a body's velocity: every number finite, every velocity in [`limits::SPEED`] (each
/// component, table value and amplitude, and the speed a rotation gives the farthest corner of
/// the body's `boxes`).
pub(crate) fn validate(
    field: &str,
    v: &BodyVelocity,
    d: usize,
    boxes: &[super::Region],
) -> Result<(), SceneError> {
    let f = match v {
        BodyVelocity::Uniform(u) => return velocities(field, u, d),
        BodyVelocity::Field(f) => f,
    };
    if let Some(l) = &f.linear {
        velocities(&format!("{field}.linear"), l, d)?;
    }
    if let Some(a) = &f.angular {
        let of = format!("{field}.angular.omega");
        match (&a.omega, d) {
            (Omega::Scalar(w), 2) => finite(&of, *w)?,
            (Omega::Vector(w), 3) => components(&of, w, 3)?,
            (Omega::Scalar(_), _) => {
                return Err(err(
                    of,
                    "a 3D scene needs the angular velocity as a vector [wx, wy, wz] (rad/s)",
                ))
            }
            (Omega::Vector(_), _) => {
                return Err(err(
                    of,
                    "a 2D scene turns about z: give the angular velocity as a number (rad/s)",
                ))
            }
        }
        components(&format!("{field}.angular.center"), &a.center, d)?;
        let w = match &a.omega {
            Omega::Scalar(w) => w.abs(),
            Omega::Vector(w) => w.iter().map(|c| c * c).sum::<f64>().sqrt(),
        };
        // The farthest box corner from the centre bounds every particle's distance.
        let r = boxes
            .iter()
            .flat_map(|b| {
                (0..1usize << d).map(move |corner| {
                    (0..d)
                        .map(|k| {
                            let x = if corner >> k & 1 == 1 {
                                b.max[k]
                            } else {
                                b.min[k]
                            };
                            (x - a.center[k]).powi(2)
                        })
                        .sum::<f64>()
                        .sqrt()
                })
            })
            .fold(0.0, f64::max);
        if !limits::SPEED.contains(w * r) {
            return Err(err(
                of,
                format!(
                    "{} rad/s turns the body's farthest corner, {} m from the centre, at {} m/s, \
                     outside the initial speed range {}",
                    num(w),
                    num(r),
                    num(w * r),
                    limits::SPEED.describe()
                ),
            ));
        }
    }
    for (k, p) in f.profiles.iter().enumerate() {
        match p {
            VelocityProfile::Table(t) => {
                let pf = format!("{field}.profiles[{k}].table");
                axis(&format!("{pf}.axis"), &t.axis, d)?;
                axis(&format!("{pf}.component"), &t.component, d)?;
                if t.points.is_empty() {
                    return Err(err(
                        format!("{pf}.points"),
                        "needs at least one [s, v] pair",
                    ));
                }
                for (j, [s, v]) in t.points.iter().enumerate() {
                    finite(&format!("{pf}.points[{j}][0]"), *s)?;
                    speed(&format!("{pf}.points[{j}][1]"), *v)?;
                    if j > 0 && *s <= t.points[j - 1][0] {
                        return Err(err(
                            format!("{pf}.points[{j}]"),
                            format!(
                                "s = {} m does not follow s = {} m of the point before: the \
                                 points must be sorted by s, each s once",
                                num(*s),
                                num(t.points[j - 1][0])
                            ),
                        ));
                    }
                }
            }
            VelocityProfile::ModeShape(m) => {
                let pf = format!("{field}.profiles[{k}].mode_shape");
                let a = axis(&format!("{pf}.axis"), &m.axis, d)?;
                let c = axis(&format!("{pf}.component"), &m.component, d)?;
                if a == c {
                    return Err(err(
                        format!("{pf}.component"),
                        format!(
                            "'{}' is the beam's axis: a bending mode moves the beam across it \
                             (use a table for a velocity along the axis)",
                            m.component
                        ),
                    ));
                }
                finite(&format!("{pf}.x0"), m.x0)?;
                if !super::limits::MODE_SHAPE_LENGTH.contains(m.length) {
                    return Err(err(
                        format!("{pf}.length"),
                        format!(
                            "must be a positive finite length (m), got {}",
                            num(m.length)
                        ),
                    ));
                }
                speed(&format!("{pf}.amplitude"), m.amplitude)?;
            }
        }
    }
    Ok(())
}

/// The variant tags of [`BodyVelocity`] and [`Omega`] in binary formats (bincode).
#[derive(Deserialize)]
enum BodyVelocityBinary {
    Uniform(Vec<f64>),
    Field(VelocityField),
}

#[derive(Deserialize)]
enum OmegaBinary {
    Scalar(f64),
    Vector(Vec<f64>),
}

impl Serialize for BodyVelocity {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match (self, s.is_human_readable()) {
            (BodyVelocity::Uniform(v), true) => v.serialize(s),
            (BodyVelocity::Field(f), true) => f.serialize(s),
            (BodyVelocity::Uniform(v), false) => {
                s.serialize_newtype_variant("BodyVelocity", 0, "Uniform", v)
            }
            (BodyVelocity::Field(f), false) => {
                s.serialize_newtype_variant("BodyVelocity", 1, "Field", f)
            }
        }
    }
}

impl<'de> Deserialize<'de> for BodyVelocity {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        if !d.is_human_readable() {
            return Ok(match BodyVelocityBinary::deserialize(d)? {
                BodyVelocityBinary::Uniform(v) => BodyVelocity::Uniform(v),
                BodyVelocityBinary::Field(f) => BodyVelocity::Field(f),
            });
        }
        struct V;
        impl<'de> de::Visitor<'de> for V {
            type Value = BodyVelocity;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str(
                    "an initial velocity: an array [vx, vy(, vz)] (m/s) or an object with \
                     `linear`, `angular`, `profiles`",
                )
            }
            fn visit_seq<A: de::SeqAccess<'de>>(self, seq: A) -> Result<BodyVelocity, A::Error> {
                Vec::<f64>::deserialize(de::value::SeqAccessDeserializer::new(seq))
                    .map(BodyVelocity::Uniform)
            }
            fn visit_map<A: de::MapAccess<'de>>(self, map: A) -> Result<BodyVelocity, A::Error> {
                VelocityField::deserialize(de::value::MapAccessDeserializer::new(map))
                    .map(BodyVelocity::Field)
            }
        }
        d.deserialize_any(V)
    }
}

impl Serialize for Omega {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match (self, s.is_human_readable()) {
            (Omega::Scalar(w), true) => w.serialize(s),
            (Omega::Vector(w), true) => w.serialize(s),
            (Omega::Scalar(w), false) => s.serialize_newtype_variant("Omega", 0, "Scalar", w),
            (Omega::Vector(w), false) => s.serialize_newtype_variant("Omega", 1, "Vector", w),
        }
    }
}

impl<'de> Deserialize<'de> for Omega {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        if !d.is_human_readable() {
            return Ok(match OmegaBinary::deserialize(d)? {
                OmegaBinary::Scalar(w) => Omega::Scalar(w),
                OmegaBinary::Vector(w) => Omega::Vector(w),
            });
        }
        struct V;
        impl<'de> de::Visitor<'de> for V {
            type Value = Omega;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str(
                    "an angular velocity (rad/s): a number in 2D, an array [wx, wy, wz] in 3D",
                )
            }
            fn visit_f64<E: de::Error>(self, w: f64) -> Result<Omega, E> {
                Ok(Omega::Scalar(w))
            }
            fn visit_i64<E: de::Error>(self, w: i64) -> Result<Omega, E> {
                Ok(Omega::Scalar(w as f64))
            }
            fn visit_u64<E: de::Error>(self, w: u64) -> Result<Omega, E> {
                Ok(Omega::Scalar(w as f64))
            }
            fn visit_seq<A: de::SeqAccess<'de>>(self, seq: A) -> Result<Omega, A::Error> {
                Vec::<f64>::deserialize(de::value::SeqAccessDeserializer::new(seq))
                    .map(Omega::Vector)
            }
        }
        d.deserialize_any(V)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The clamped-free mode: zero value and slope at the clamp, zero moment and shear (second
    /// and third derivative) at the free end, 1 at the tip; checked by finite differences.
    #[test]
    fn clamped_free_mode_satisfies_the_beam_end_conditions() {
        let l = 0.2;
        let f = |s: f64| ModeShape::ClampedFree1.normalised(s, l);
        let h = 1e-3 * l;
        assert_eq!(f(0.0), 0.0);
        assert!((f(l) - 1.0).abs() < 1e-15);
        // Slope at the clamp (one-sided, O(h)): f ~ s^2 near 0.
        assert!(f(h) / h < 1e-2, "slope {}", f(h) / h);
        // Curvature at the tip relative to the curvature at the clamp (kL^2 f(L)-scaled).
        let d2 = |s: f64| (f(s + h) - 2.0 * f(s) + f(s - h)) / (h * h);
        let d3 = |s: f64| {
            (f(s + 2.0 * h) - 2.0 * f(s + h) + 2.0 * f(s - h) - f(s - 2.0 * h)) / (2.0 * h * h * h)
        };
        let c0 = d2(2.0 * h);
        // The free end evaluated just inside it (central differences need s + 2h <= L).
        let tip = l - 2.0 * h;
        assert!(d2(tip).abs() < 2e-2 * c0.abs(), "{} vs {c0}", d2(tip));
        assert!(d3(tip).abs() * l < 5e-2 * c0.abs(), "{} vs {c0}", d3(tip));
        // Monotonic from clamp to tip.
        let mut prev = 0.0;
        for k in 1..=100 {
            let v = f(l * k as f64 / 100.0);
            assert!(v > prev);
            prev = v;
        }
        // Clamped outside [0, L].
        assert_eq!(f(-1.0), 0.0);
        assert!((f(2.0 * l) - 1.0).abs() < 1e-15);
    }

    #[test]
    fn table_interpolates_and_is_constant_beyond_its_ends() {
        let t = [[0.0, 1.0], [1.0, 3.0], [3.0, -1.0]];
        assert_eq!(table_at(&t, -5.0), 1.0);
        assert_eq!(table_at(&t, 0.0), 1.0);
        assert_eq!(table_at(&t, 0.5), 2.0);
        assert_eq!(table_at(&t, 1.0), 3.0);
        assert_eq!(table_at(&t, 2.0), 1.0);
        assert_eq!(table_at(&t, 3.0), -1.0);
        assert_eq!(table_at(&t, 9.0), -1.0);
        assert_eq!(table_at(&[[2.0, 7.0]], 0.0), 7.0);
    }

    #[test]
    fn binary_formats_round_trip() {
        let v = BodyVelocity::Field(VelocityField {
            linear: Some(vec![1.0, 2.0, 3.0]),
            angular: Some(AngularVelocity {
                omega: Omega::Vector(vec![0.0, 0.0, 2.0]),
                center: vec![0.0; 3],
            }),
            profiles: vec![VelocityProfile::ModeShape(ModeShapeProfile {
                shape: ModeShape::ClampedFree1,
                axis: "x".into(),
                component: "z".into(),
                x0: 0.0,
                length: 1.0,
                amplitude: 0.5,
            })],
        });
        for v in [v, BodyVelocity::Uniform(vec![1.0, 2.0])] {
            let b = bincode::serialize(&v).unwrap();
            assert_eq!(bincode::deserialize::<BodyVelocity>(&b).unwrap(), v);
            let j = serde_json::to_string(&v).unwrap();
            assert_eq!(serde_json::from_str::<BodyVelocity>(&j).unwrap(), v);
        }
    }
}
