//! The physically meaningful ranges of a scene's numbers, in one table: read by the scene
//! validation, by the FMI layer (min/max of the parameters in the modelDescription and the range
//! check of fmi2SetReal) and by the command line. Also the number format of error messages.

/// A closed range [min, max] of a number, with its unit. Closed so that it maps one to one onto
/// the FMI `min`/`max` attributes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Range {
    /// Field path of the number below its owner ("material.density", "solver.dt", "end_time").
    pub field: &'static str,
    /// Smallest accepted value.
    pub min: f64,
    /// Largest accepted value.
    pub max: f64,
    /// Unit as written in messages and the modelDescription ("" when dimensionless).
    pub unit: &'static str,
}

impl Range {
    /// Whether v lies in [min, max] (NaN never does).
    pub fn contains(&self, v: f64) -> bool {
        v >= self.min && v <= self.max
    }

    /// Ok when v is in range, else the message "must be in [min, max] unit, got v".
    pub fn check(&self, v: f64) -> Result<(), String> {
        if self.contains(v) {
            Ok(())
        } else {
            Err(format!("must be in {}, got {}", self.describe(), num(v)))
        }
    }

    /// "[min, max] unit".
    pub fn describe(&self) -> String {
        let unit = if self.unit.is_empty() {
            String::new()
        } else {
            format!(" {}", self.unit)
        };
        format!("[{}, {}]{unit}", num(self.min), num(self.max))
    }
}

/// Density rho (kg/m^3). The lightest solids (aerogels) are about 0.2 kg/m^3, the densest
/// element (osmium) 22,590 kg/m^3; the bounds leave two decades below and a factor 4 above.
pub const DENSITY: Range = Range {
    field: "material.density",
    min: 1e-3,
    max: 1e5,
    unit: "kg/m3",
};

/// Young's modulus E (Pa). Soft gels and tissue are about 100 Pa to 1 kPa, diamond and graphene
/// about 1.2e12 Pa; an order of magnitude is left on either side.
pub const YOUNG: Range = Range {
    field: "material.young",
    min: 1.0,
    max: 1e13,
    unit: "Pa",
};

/// Poisson's ratio nu (-). Theory allows (-1, 0.5). Near 0.5 the material is incompressible:
/// lambda / mu = 2 nu / (1 - 2 nu) is 499 at nu = 0.499, so the pressure wave is already 22x
/// faster than the shear wave (22x more explicit steps than at nu = 0) and the volumetric term
/// is a difference of nearly equal numbers; at 0.49999999999999994 lambda / mu is about 9e15 and
/// the stable step collapses to round-off. 0.499 is also the usual "nearly incompressible"
/// value of rubber models. The lower bound mirrors it: at nu = -0.999, mu / K is about 750.
pub const POISSON: Range = Range {
    field: "material.poisson",
    min: -0.999,
    max: 0.499,
    unit: "",
};

/// A fixed solver time step (s). The stable step of any accepted material and spacing is far
/// above 1e-12 s for dp >= 1 um; a step beyond 1000 s resolves no elastic motion. The work is
/// bounded separately by `solver.max_steps`.
pub const SOLVER_DT: Range = Range {
    field: "solver.dt",
    min: 1e-12,
    max: 1e3,
    unit: "s",
};

/// Safety factor on the stable step (-). Below 0.01 a run costs 80x the default (0.8) with no
/// gain: the time error of the symplectic scheme at 0.8 is already far below the spatial one.
/// Above 0.8 is not allowed (issue 7): the step bound is measured in the reference
/// configuration and again as the body deforms (docs/model.md), but a soft body collapsing
/// under its load stiffens faster than the refreshes follow (small2d variants with E = 1e3-1e6
/// Pa under gravity up to 100 g: omega_max +8 % to +35 % over the run) and blew up at safety
/// 0.85-1.0 while all ran at 0.8 (tests/stability_step.rs).
pub const SAFETY: Range = Range {
    field: "solver.safety",
    min: 0.01,
    max: 0.8,
    unit: "",
};

/// Mass-proportional damping c (1/s). c = 1e6 1/s damps a particle in 1 us, faster than any
/// elastic wave crosses a particle of an accepted scene; the explicit update v (1 - c dt) needs
/// c dt < 2 in any case.
pub const DAMPING: Range = Range {
    field: "solver.damping",
    min: 0.0,
    max: 1e6,
    unit: "1/s",
};

/// Critical bond strain eps_max of Eq. (42) (-) when fracture is on. Bonds of brittle solids
/// break at strains of 1e-4..1e-2 and rubber at about 7; 1e-6 is below the round-off of a
/// strain measured on coordinates of order 1e3 dp, 10 (1000 %) above any solid.
pub const FRACTURE_STRAIN: Range = Range {
    field: "solver.fracture_strain",
    min: 1e-6,
    max: 10.0,
    unit: "",
};

/// Simulated time (s). From a nanosecond to about 30 years; what a run of that length costs is
/// bounded by `solver.max_steps`.
pub const END_TIME: Range = Range {
    field: "end_time",
    min: 1e-9,
    max: 1e9,
    unit: "s",
};

/// Interval of the probe time series (s).
pub const OUTPUT_INTERVAL: Range = Range {
    field: "output_interval",
    min: 1e-9,
    max: 1e9,
    unit: "s",
};

/// Initial velocity of a body (m/s): each component of `bodies[].velocity` (uniform or
/// linear), each value of a velocity table, a mode shape's amplitude, and the speed a rotation
/// gives the body's farthest corner. Impacts on spacecraft shielding reach about 1e4 m/s and
/// meteoroids 7e4 m/s; beyond 1e5 m/s no solid model applies (and a particle would cross its
/// spacing in a small fraction of any stable step).
pub const SPEED: Range = Range {
    field: "velocity",
    min: -1e5,
    max: 1e5,
    unit: "m/s",
};

/// Largest number of probe samples end_time / output_interval of a run: the series is kept in
/// memory and written as CSV (1e6 samples of 10 probes is about 240 MB).
pub const MAX_OUTPUTS: f64 = 1e6;

/// Wall-clock bound of the model's set-up (s). From a second (a test's quick refusal) to a
/// week.
pub const MAX_SETUP_SECONDS: Range = Range {
    field: "solver.max_setup_seconds",
    min: 1.0,
    max: 604_800.0,
    unit: "s",
};

/// Every closed range above: the JSON Schema of the scene (src/scene/schema.rs) states each as the
/// `minimum`/`maximum` of its field.
pub const RANGES: &[Range] = &[
    DENSITY,
    YOUNG,
    POISSON,
    SOLVER_DT,
    SAFETY,
    DAMPING,
    FRACTURE_STRAIN,
    END_TIME,
    OUTPUT_INTERVAL,
    MAX_SETUP_SECONDS,
];

/// A bound of a scene number that is not an FMI parameter (so not a closed [`Range`]): one- or
/// two-sided, each side inclusive or exclusive. The scene validation tests values with
/// [`Bound::contains`]; the JSON Schema states it (`minimum`/`exclusiveMinimum`, ...).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bound {
    /// Field path of the number below its owner, as in [`Range::field`].
    pub field: &'static str,
    /// Lower limit, if any.
    pub min: Option<f64>,
    /// Whether the lower limit itself is refused.
    pub min_exclusive: bool,
    /// Upper limit, if any.
    pub max: Option<f64>,
    /// Whether the upper limit itself is refused.
    pub max_exclusive: bool,
}

impl Bound {
    /// Greater than zero, finite.
    const fn positive(field: &'static str) -> Bound {
        Bound {
            field,
            min: Some(0.0),
            min_exclusive: true,
            max: None,
            max_exclusive: false,
        }
    }

    /// At least `min`, finite.
    const fn at_least(field: &'static str, min: f64) -> Bound {
        Bound {
            field,
            min: Some(min),
            min_exclusive: false,
            max: None,
            max_exclusive: false,
        }
    }

    /// Whether v is finite and within the bound (NaN and infinities never are).
    pub fn contains(&self, v: f64) -> bool {
        v.is_finite()
            && self
                .min
                .is_none_or(|m| if self.min_exclusive { v > m } else { v >= m })
            && self
                .max
                .is_none_or(|m| if self.max_exclusive { v < m } else { v <= m })
    }

    /// "(1, 4]", "[0, 1)", ">= 1", "> 0".
    pub fn describe(&self) -> String {
        match (self.min, self.max) {
            (Some(a), Some(b)) => format!(
                "{}{}, {}{}",
                if self.min_exclusive { "(" } else { "[" },
                num(a),
                num(b),
                if self.max_exclusive { ")" } else { "]" }
            ),
            (Some(a), None) => {
                format!("{} {}", if self.min_exclusive { ">" } else { ">=" }, num(a))
            }
            (None, Some(b)) => {
                format!("{} {}", if self.max_exclusive { "<" } else { "<=" }, num(b))
            }
            (None, None) => "any finite number".to_string(),
        }
    }
}

/// The scene's dimension: 2 or 3.
pub const DIMENSION: Bound = Bound {
    field: "dimension",
    min: Some(2.0),
    min_exclusive: false,
    max: Some(3.0),
    max_exclusive: false,
};

/// Initial particle spacing l0 (m).
pub const PARTICLE_SPACING: Bound = Bound::positive("particle_spacing");

/// Period T of the paper's gravity ramp, Eq. (46) (s).
pub const RAMP_PERIOD: Bound = Bound::positive("gravity.paper_ramp_period");

/// re / l0 (-): above 1, or a particle has no neighbour on the lattice; 4 already bonds about
/// 200 neighbours in 3D (the paper uses 2.1).
pub const RE_FACTOR: Bound = Bound {
    field: "solver.re_factor",
    min: Some(1.0),
    min_exclusive: true,
    max: Some(4.0),
    max_exclusive: false,
};

/// Stiffness factor of the corrected operator's stabilisation (-): a stiffness, not negative.
pub const STABILISATION: Bound = Bound::at_least("solver.stabilisation", 0.0);

/// Steps of one advance (work guard): at least one.
pub const MAX_STEPS: Bound = Bound::at_least("solver.max_steps", 1.0);

/// Particle-steps (steps times particles) of one advance (work guard): at least one.
pub const MAX_PARTICLE_STEPS: Bound = Bound::at_least("solver.max_particle_steps", 1.0);

/// n_c of Eq. (41) (-): a positive number-density margin.
pub const SURFACE_THRESHOLD: Bound = Bound::positive("solver.contact.surface_threshold");

/// Overlap distance as a fraction of l0 (-): strictly between touching and a full spacing.
pub const OVERLAP_FRACTION: Bound = Bound {
    field: "solver.contact.overlap_fraction",
    min: Some(0.0),
    min_exclusive: true,
    max: Some(1.0),
    max_exclusive: true,
};

/// Contact stiffness multiplier (-).
pub const CONTACT_STIFFNESS: Bound = Bound::positive("solver.contact.stiffness");

/// Verlet skin of the contact pair list, a fraction of l0 (-).
pub const CONTACT_SKIN: Bound = Bound::positive("solver.contact.skin");

/// Contact partners per particle assumed by the stable step (-): at least one.
pub const MAX_PARTNERS: Bound = Bound::at_least("solver.contact.max_partners", 1.0);

/// Length of a mode-shape velocity profile's beam (m).
pub const MODE_SHAPE_LENGTH: Bound = Bound::positive("mode_shape.length");

/// Every bound above: the scene validation checks each, the JSON Schema states each.
pub const BOUNDS: &[Bound] = &[
    DIMENSION,
    PARTICLE_SPACING,
    RAMP_PERIOD,
    RE_FACTOR,
    STABILISATION,
    MAX_STEPS,
    MAX_PARTICLE_STEPS,
    SURFACE_THRESHOLD,
    OVERLAP_FRACTION,
    CONTACT_STIFFNESS,
    CONTACT_SKIN,
    MAX_PARTNERS,
    MODE_SHAPE_LENGTH,
];

/// Defaults of `solver.max_steps`, `solver.max_particle_steps`, `solver.max_particles` and
/// `solver.max_setup_seconds` (kept with the solver options).
pub use crate::physics::params::{
    DEFAULT_MAX_PARTICLES, DEFAULT_MAX_PARTICLE_STEPS, DEFAULT_MAX_STEPS,
};

/// A number for a message: the shortest text that reads back to the same f64, in plain notation
/// for 1e-4 <= |v| < 1e7 and in scientific notation otherwise (never hundreds of digits).
pub fn num(v: f64) -> String {
    if !v.is_finite() {
        return format!("{v}");
    }
    let a = v.abs();
    if a == 0.0 || (1e-4..1e7).contains(&a) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_are_short_and_exact() {
        assert_eq!(num(1e-300), "1e-300");
        assert_eq!(num(1e300), "1e300");
        assert_eq!(num(0.49999999999999994), "0.49999999999999994");
        assert_eq!(num(0.0), "0");
        assert_eq!(num(2.5), "2.5");
        assert_eq!(num(-1.25e-7), "-1.25e-7");
        assert_eq!(num(f64::NAN), "NaN");
        assert_eq!(num(f64::NEG_INFINITY), "-inf");
        for v in [
            1e-300,
            0.1 + 0.2,
            123456.789,
            9.99e6,
            1.7976931348623157e308,
        ] {
            assert_eq!(num(v).parse::<f64>().unwrap(), v);
            assert!(num(v).len() <= 24, "{}", num(v));
        }
    }

    #[test]
    fn ranges_hold_the_paper_values_and_refuse_the_absurd() {
        assert!(DENSITY.contains(1000.0) && !DENSITY.contains(1e-30));
        assert!(YOUNG.contains(6e6) && YOUNG.contains(1e12) && !YOUNG.contains(1e30));
        assert!(POISSON.contains(0.3) && !POISSON.contains(0.49999999999999994));
        assert!(!SOLVER_DT.contains(1e-30) && SOLVER_DT.contains(1e-5));
        assert!(!SAFETY.contains(1e-300) && SAFETY.contains(0.8));
        assert!(!DENSITY.contains(f64::NAN));
        assert_eq!(
            POISSON.check(0.5).unwrap_err(),
            "must be in [-0.999, 0.499], got 0.5"
        );
        assert_eq!(
            DENSITY.check(1e-30).unwrap_err(),
            "must be in [0.001, 100000] kg/m3, got 1e-30"
        );
    }
}
