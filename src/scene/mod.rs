//! Scenes as serde data (JSON or TOML): bodies as boxes and shapes (module `shape`: cylinders,
//! spheres, half-space cuts, STL meshes) filled with particles, materials, boundary groups and
//! load regions selected by region and shape, gravity with the paper's ramp, probes, run
//! settings. `Scene::validate` names the field and the problem for every bad input; `build`
//! makes a World.
mod build;
mod fill;
pub mod limits;
pub mod memory;
pub mod resolution;
pub mod schema;
pub mod shape;
pub mod surface;
pub mod velocity;

pub use build::{Model, ProbeAt};
use limits::num;
pub use resolution::{SceneWarning, THIN_BENDING_ERRORS};
pub use shape::{Cylinder, HalfSpace, MeshSpec, Shape, Sphere};
pub use velocity::{
    AngularVelocity, BodyVelocity, ModeShape, ModeShapeProfile, Omega, TableProfile, VelocityField,
    VelocityProfile,
};

use crate::physics::{ElasticModel, Material, MaterialLaw, SolverOptions};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// A scene file: the bodies as boxes of particles, their materials, boundary groups, load
/// regions, probes and the run's settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// Short identifier (also the FMU model identifier); letters, digits and '_'.
    pub name: String,
    /// Free text: what the scene is and the choices the paper leaves open.
    #[serde(default)]
    pub description: String,
    /// 2 or 3.
    pub dimension: usize,
    /// Initial particle spacing l0 = dp (m).
    pub particle_spacing: f64,
    /// The elasticity operator, time step, fracture and contact settings.
    #[serde(default)]
    pub solver: SolverOptions,
    /// Gravity acting on every particle (default: none).
    #[serde(default)]
    pub gravity: Gravity,
    /// The solids, at least one.
    pub bodies: Vec<Body>,
    /// Boundary groups: clamped, pinned or prescribed particles of a body.
    #[serde(default)]
    pub boundaries: Vec<Boundary>,
    /// Load regions: particles sharing an external force set from outside (FMU inputs).
    #[serde(default)]
    pub loads: Vec<LoadSpec>,
    /// Points whose displacement is reported (time series, FMU outputs).
    #[serde(default)]
    pub probes: Vec<Probe>,
    /// Simulated time (s).
    pub end_time: f64,
    /// Interval of the probe time series (s).
    pub output_interval: f64,
    /// What to measure from the probe series (optional).
    #[serde(default)]
    pub analysis: Option<Analysis>,
    /// The folder that relative mesh files (`bodies[].shapes[].mesh.file`) are read from: the
    /// scene file's (set by `Scene::load`; an FMU's resources folder). Not part of the file.
    #[serde(skip)]
    pub base_dir: Option<PathBuf>,
}

/// Gravity: a vector (m/s^2) and an optional ramp.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Default, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Gravity {
    /// Full gravity vector (m/s^2), `dimension` components.
    pub vector: Vec<f64>,
    /// Eq. (46) with this T (s): the full vector is reached smoothly at 0.2 T. None: sudden.
    #[serde(default)]
    pub paper_ramp_period: Option<f64>,
}

/// An axis-aligned box (m), `dimension` components each. As a selection (boundaries, loads)
/// it may be left out when a `shape` selects: then `min` and `max` are empty.
#[derive(Clone, Debug, PartialEq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Region {
    /// The lower corner (m), `dimension` components.
    pub min: Vec<f64>,
    /// The upper corner (m), `dimension` components, not below `min`.
    pub max: Vec<f64>,
}

/// A body: boxes filled with particles at the centres of cells of side `particle_spacing`.
/// Particles of all boxes of a body are bonded together; a particle closer than l0 / 4 to one of
/// an earlier box is dropped. A later box with another lattice offset puts a layer of particles
/// exactly on a face (used for supports: see docs/model.md).
///
/// A body with `shapes` or `cuts` is the union of its boxes and shapes less its cuts, filled on
/// one lattice: the cell centres at `boxes[0].min` + (i + 1/2) l0 that lie inside (at
/// (i + 1/2) l0 without boxes; a solid that is one box given as shapes has its cells centred on
/// it: a side of a whole number of spacings on cell faces, any other cut alike at both ends). Each particle's volume (and mass) is the part of the solid in its cell,
/// plus the parts of cells next to it whose centres fall outside, so the body's volume is the
/// solid's (not a staircase's); surface particles carry the solid's outward normal and area.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Body {
    /// Unique name of the body (boundaries, loads and probes refer to it).
    pub name: String,
    /// The body's elastic material.
    pub material: Material,
    /// Extents (m); each side must be a whole number of particle spacings. May be empty when
    /// `shapes` is not.
    #[serde(default)]
    pub boxes: Vec<Region>,
    /// Further solids of the body (their union with the boxes): `{"cylinder": ..}`,
    /// `{"sphere": ..}`, `{"box": ..}`, `{"mesh": ..}` (module `shape`). Default none.
    #[serde(default)]
    pub shapes: Vec<Shape>,
    /// Solids removed from the body (difference), half-spaces too. Default none.
    #[serde(default)]
    pub cuts: Vec<Shape>,
    /// Initial velocity: `[vx, vy(, vz)]` (m/s, the same for every particle), or a field
    /// `{"linear": [..], "angular": {"omega": .., "center": [..]}, "profiles": [..]}` summed
    /// at each particle's reference position (see [`BodyVelocity`], module `velocity`). Particles
    /// of boundary groups start at rest along their held axes. None (null): at rest.
    #[serde(default)]
    pub velocity: Option<BodyVelocity>,
}

/// Kind of boundary group.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum BoundaryKind {
    /// Translation along all axes and rotation held (displacement settable from outside).
    Clamped,
    /// Translation held along `axes`, rotation free.
    Pinned,
    /// Translation along `axes` follows a displacement set from outside; rotation held.
    Prescribed,
}

/// A boundary group: the particles of `body` inside `region` and `shape`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Boundary {
    /// Unique name of the group (the FMU's `<name>.u*` displacement inputs).
    pub name: String,
    /// What the group holds.
    pub kind: BoundaryKind,
    /// Name of the body whose particles the group takes.
    pub body: String,
    /// The box the group's particles lie in (m, with a 1e-9 l0 margin); may be left out when
    /// `shape` selects.
    #[serde(default)]
    pub region: Region,
    /// A shape the group's particles lie in (with a 1e-6 l0 margin), besides `region`.
    #[serde(default)]
    pub shape: Option<Shape>,
    /// Axes ("x", "y", "z") for pinned and prescribed groups; default all.
    #[serde(default)]
    pub axes: Option<Vec<String>>,
    /// The boundary face the group mirrors its body across (second_order model only): the
    /// group's layers sit at the mirror images of the body's particles (a box [-3 l0, 0] beside a
    /// body that starts at 0, over the same section, with no layer on the face), and each acts
    /// as its image's reflection, odd on the held axes and even on the free ones. A clamp so
    /// holds u = 0 on the face and a face support with the normal axis free holds the
    /// tangential displacement with no normal stress, both without the one-sided fits next to
    /// the face (their O(l0) slip; docs/model.md, "Mirror faces"). Default: none, and none is
    /// needed where the face follows from the geometry: a clamp beside one face of its body
    /// (walls behind it, the body's own end layers or a layer on the face), and a support whose
    /// layers fill the lattice beyond one whole face of its body as deep as the stencil
    /// reaches (2 layers at re = 2.1 dp). Any other group is held as it is written. Always
    /// serialised (null when absent): FMU states are bincode, which cannot skip fields.
    #[serde(default)]
    pub mirror: Option<MirrorSpec>,
}

/// A plane: the boundary face of a mirror group.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct MirrorSpec {
    /// A point of the face (m), `dimension` components.
    pub point: Vec<f64>,
    /// The face's normal (-): any length but not zero, `dimension` components.
    pub normal: Vec<f64>,
}

/// A load region: the particles of `body` inside `region` and `shape` share an external force.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct LoadSpec {
    /// Unique name of the load region (the FMU's `<name>.F*` force inputs).
    pub name: String,
    /// Name of the body whose particles share the force.
    pub body: String,
    /// The box the particles lie in (m); may be left out when `shape` selects.
    #[serde(default)]
    pub region: Region,
    /// A shape the particles lie in (with a 1e-6 l0 margin), besides `region`.
    #[serde(default)]
    pub shape: Option<Shape>,
}

/// A named point of a body whose displacement is reported (reference coordinates, m).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Probe {
    /// Unique name of the probe (the FMU's `<name>.u*` outputs, the series' columns).
    pub name: String,
    /// The point (m), reference coordinates, `dimension` components; the nearest particle is
    /// reported.
    pub point: Vec<f64>,
    /// The body the point belongs to; default: the body whose boxes or shapes contain it.
    #[serde(default)]
    pub body: Option<String>,
}

/// Measurements a scene asks for.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Analysis {
    /// Probe whose displacement component gives the vibration frequency and peak deflection.
    pub probe: String,
    /// Component: "x", "y" or "z".
    pub component: String,
}

/// A scene problem: which field and what is wrong.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("scene error in {field}: {message}")]
pub struct SceneError {
    pub field: String,
    pub message: String,
}

pub(crate) fn err(field: impl Into<String>, message: impl Into<String>) -> SceneError {
    SceneError {
        field: field.into(),
        message: message.into(),
    }
}

/// Index of an axis name.
pub fn axis_index(name: &str) -> Option<usize> {
    match name {
        "x" => Some(0),
        "y" => Some(1),
        "z" => Some(2),
        _ => None,
    }
}

impl Scene {
    /// Parses JSON: exactly one scene object, nothing but whitespace after it. A top-level
    /// `"$schema"` (the schema's address, for editors) is passed over. Relative mesh files are
    /// read from the current folder.
    pub fn from_json(text: &str) -> Result<Scene, SceneError> {
        Scene::from_json_in(text, None)
    }

    /// Parses JSON whose relative mesh files are in `base_dir`.
    pub fn from_json_in(text: &str, base_dir: Option<&Path>) -> Result<Scene, SceneError> {
        let mut de = serde_json::Deserializer::from_str(text);
        let mut s: Scene = serde_path_to_error::deserialize(schema::SkipSchemaKey(&mut de))
            .map_err(|e| err(e.path().to_string(), in_words(&e.inner().to_string())))?;
        de.end().map_err(|e| {
            err(
                "<end of the scene>",
                format!(
                    "{e}: only whitespace may follow the scene object (two scenes in one file?)"
                ),
            )
        })?;
        s.base_dir = base_dir.map(Path::to_path_buf);
        s.validate()?;
        Ok(s)
    }
    /// Parses TOML.
    pub fn from_toml(text: &str) -> Result<Scene, SceneError> {
        Scene::from_toml_in(text, None)
    }
    /// Parses TOML whose relative mesh files are in `base_dir`.
    pub fn from_toml_in(text: &str, base_dir: Option<&Path>) -> Result<Scene, SceneError> {
        let de = toml::Deserializer::new(text);
        let mut s: Scene =
            serde_path_to_error::deserialize(schema::SkipSchemaKey(de)).map_err(|e| {
                let field = e.path().to_string();
                let inner = e.into_inner();
                // One line: the reason and where (toml's own text adds a snippet of the file).
                let at = inner.span().map_or(String::new(), |span| {
                    let before = &text[..span.start.min(text.len())];
                    let line = before.matches('\n').count() + 1;
                    let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
                    format!(" (line {line}, column {column})")
                });
                err(
                    field,
                    format!("{}{at}", in_words(inner.message().trim_end())),
                )
            })?;
        s.base_dir = base_dir.map(Path::to_path_buf);
        s.validate()?;
        Ok(s)
    }
    /// Reads a .json or .toml file.
    pub fn load(path: &Path) -> Result<Scene, SceneError> {
        let size = std::fs::metadata(path)
            .map_err(|e| err("<file>", format!("cannot read {}: {e}", path.display())))?
            .len();
        if size > MAX_SCENE_BYTES {
            return Err(err(
                "<file>",
                format!(
                    "{} is {size} bytes long, more than a scene file may be ({MAX_SCENE_BYTES})",
                    path.display()
                ),
            ));
        }
        let text = std::fs::read_to_string(path)
            .map_err(|e| err("<file>", format!("cannot read {}: {e}", path.display())))?;
        // Mesh files are relative to the scene file's folder.
        let dir = path.parent().map(|d| {
            if d.as_os_str().is_empty() {
                Path::new(".")
            } else {
                d
            }
        });
        match path.extension().and_then(|e| e.to_str()) {
            Some("toml") => Scene::from_toml_in(&text, dir),
            _ => Scene::from_json_in(&text, dir),
        }
    }
    /// Serialises to pretty JSON (the canonical form the FMU's GUID hashes: no `$schema`).
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("scene serialises")
    }

    /// Pretty JSON that names its schema first (`"$schema": schema`, the address relative to
    /// the file or a URL), for scene files that editors check; reads back as the same scene.
    pub fn to_json_with_schema(&self, schema: &str) -> String {
        let json = self.to_json();
        let body = json
            .strip_prefix('{')
            .expect("a scene serialises to an object");
        format!(
            "{{\n  {}: {},{body}",
            serde_json::to_string(schema::SCHEMA_KEY).expect("a string serialises"),
            serde_json::to_string(schema).expect("a string serialises")
        )
    }

    /// Checks every field; the first problem found is returned with its field path.
    pub fn validate(&self) -> Result<(), SceneError> {
        let d = self.dimension;
        if !limits::DIMENSION.contains(d as f64) {
            return Err(err("dimension", format!("must be 2 or 3, got {d}")));
        }
        if self.name.is_empty()
            || !self
                .name
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '_')
            || self.name.starts_with(|c: char| c.is_ascii_digit())
        {
            return Err(err("name", format!("{:?} must be a non-empty identifier of letters, digits and '_' not starting with a digit", self.name)));
        }
        xml_text("description", &self.description, true)?;
        positive(&limits::PARTICLE_SPACING, self.particle_spacing)?;
        let o = &self.solver;
        bounded(&limits::RE_FACTOR, o.re_factor)?;
        bounded(&limits::STABILISATION, o.stabilisation)?;
        if let Some(dt) = o.dt {
            ranged("", &limits::SOLVER_DT, dt)?;
        }
        ranged("", &limits::SAFETY, o.safety)?;
        ranged("", &limits::DAMPING, o.damping)?;
        if let Some(e) = o.fracture_strain {
            ranged("", &limits::FRACTURE_STRAIN, e)?;
        }
        bounded(&limits::MAX_STEPS, o.max_steps as f64)?;
        bounded(&limits::MAX_PARTICLE_STEPS, o.max_particle_steps as f64)?;
        ranged("", &limits::MAX_SETUP_SECONDS, o.max_setup_seconds)?;
        let c = &o.contact;
        bounded(&limits::SURFACE_THRESHOLD, c.surface_threshold)?;
        bounded(&limits::OVERLAP_FRACTION, c.overlap_fraction)?;
        positive(&limits::CONTACT_STIFFNESS, c.stiffness)?;
        positive(&limits::CONTACT_SKIN, c.skin)?;
        bounded(&limits::MAX_PARTNERS, c.max_partners)?;
        ranged("", &limits::END_TIME, self.end_time)?;
        ranged("", &limits::OUTPUT_INTERVAL, self.output_interval)?;
        let outputs = self.end_time / self.output_interval;
        if outputs > limits::MAX_OUTPUTS {
            return Err(err(
                "output_interval",
                format!(
                    "{} s gives {} samples over end_time = {} s, more than {}",
                    num(self.output_interval),
                    num(outputs.ceil()),
                    num(self.end_time),
                    num(limits::MAX_OUTPUTS)
                ),
            ));
        }
        if !self.gravity.vector.is_empty() {
            vector("gravity.vector", &self.gravity.vector, d)?;
        }
        if let Some(t) = self.gravity.paper_ramp_period {
            positive(&limits::RAMP_PERIOD, t)?;
        }
        if self.bodies.is_empty() {
            return Err(err("bodies", "a scene needs at least one body"));
        }
        for (k, b) in self.bodies.iter().enumerate() {
            xml_text(&format!("bodies[{k}].name"), &b.name, false)?;
            let f = body_field(k, b);
            if self.bodies[..k].iter().any(|o| o.name == b.name) {
                return Err(err(format!("{f}.name"), "duplicate body name"));
            }
            let m = &b.material;
            ranged(&f, &limits::DENSITY, m.density)?;
            ranged(&f, &limits::YOUNG, m.young)?;
            ranged(&f, &limits::POISSON, m.poisson)?;
            if m.law != MaterialLaw::SaintVenantKirchhoff
                && matches!(
                    self.solver.model,
                    ElasticModel::Paper | ElasticModel::PaperLocal
                )
            {
                return Err(err(
                    format!("{f}.material.law"),
                    format!(
                        "\"{}\" needs an operator with a strain energy density (solver.model \"corrected\" or \"second_order\"); the paper's spring operators (solver.model \"paper\", \"paper_local\") take only the default \"saint_venant_kirchhoff\"",
                        m.law.name()
                    ),
                ));
            }
            if b.boxes.is_empty() && b.shapes.is_empty() {
                return Err(err(
                    format!("{f}.boxes"),
                    "a body needs at least one box or shape (bodies[].shapes)",
                ));
            }
            for (j, r) in b.boxes.iter().enumerate() {
                self.cell_counts(r, &format!("{f}.boxes[{j}]"))?;
            }
            let base = self.base_dir.as_deref();
            for (j, s) in b.shapes.iter().enumerate() {
                shape::check(
                    &format!("{f}.shapes[{j}]"),
                    s,
                    d,
                    self.particle_spacing,
                    true,
                    base,
                )?;
            }
            for (j, s) in b.cuts.iter().enumerate() {
                shape::check(
                    &format!("{f}.cuts[{j}]"),
                    s,
                    d,
                    self.particle_spacing,
                    false,
                    base,
                )?;
            }
            if let Some(v) = &b.velocity {
                velocity::validate(&format!("{f}.velocity"), v, d, &b.boxes)?;
            }
        }
        let total = self.particle_bound();
        if total > self.solver.max_particles as f64 {
            return Err(err(
                "bodies",
                format!(
                    "{} exceed solver.max_particles = {}",
                    memory::particles_text(self),
                    self.solver.max_particles
                ),
            ));
        }
        for (k, g) in self.boundaries.iter().enumerate() {
            xml_text(&format!("boundaries[{k}].name"), &g.name, false)?;
            let f = format!("boundaries[{k}] ('{}')", g.name);
            self.body_index(&g.body)
                .ok_or_else(|| err(format!("{f}.body"), format!("no body named '{}'", g.body)))?;
            self.selection(&f, &g.region, g.shape.as_ref())?;
            if self.boundaries[..k].iter().any(|o| o.name == g.name) {
                return Err(err(format!("{f}.name"), "duplicate boundary name"));
            }
            if let Some(m) = &g.mirror {
                vector(&format!("{f}.mirror.point"), &m.point, d)?;
                vector(&format!("{f}.mirror.normal"), &m.normal, d)?;
                if m.normal.iter().all(|c| *c == 0.0) {
                    return Err(err(format!("{f}.mirror.normal"), "must not be zero"));
                }
                // The bodies are boxes on an axis-aligned lattice: a face is normal to an axis.
                if m.normal.iter().filter(|c| **c != 0.0).count() > 1 {
                    return Err(err(
                        format!("{f}.mirror.normal"),
                        format!(
                            "{:?} is oblique; a mirror face is a face of the body's boxes, normal to x, y or z (e.g. [-1, 0{}] for a face whose outside is towards -x)",
                            m.normal,
                            if d == 3 { ", 0" } else { "" }
                        ),
                    ));
                }
                if self.solver.model != crate::physics::ElasticModel::SecondOrder {
                    return Err(err(
                        format!("{f}.mirror"),
                        "mirror faces are a feature of the second_order model (solver.model); the other models would treat the layers as walls",
                    ));
                }
            }
            if let Some(axes) = &g.axes {
                if axes.is_empty() {
                    return Err(err(format!("{f}.axes"), "must name at least one axis"));
                }
                for a in axes {
                    if axis_index(a).is_none_or(|i| i >= d) {
                        return Err(err(
                            format!("{f}.axes"),
                            format!("'{a}' is not an axis of a {d}D scene"),
                        ));
                    }
                }
                // A clamp holds every axis: a shorter list would be ignored.
                let held = (0..d)
                    .filter(|&i| axes.iter().any(|a| axis_index(a) == Some(i)))
                    .count();
                if g.kind == BoundaryKind::Clamped && held < d {
                    return Err(err(
                        format!("{f}.axes"),
                        format!(
                            "a clamped group holds every axis, so {axes:?} would be ignored; remove axes, or use kind \"pinned\" (the listed axes held, the rest free) or \"prescribed\" (the listed axes moved from outside)"
                        ),
                    ));
                }
            }
        }
        for (k, l) in self.loads.iter().enumerate() {
            xml_text(&format!("loads[{k}].name"), &l.name, false)?;
            let f = format!("loads[{k}] ('{}')", l.name);
            self.body_index(&l.body)
                .ok_or_else(|| err(format!("{f}.body"), format!("no body named '{}'", l.body)))?;
            self.selection(&f, &l.region, l.shape.as_ref())?;
            if self.loads[..k].iter().any(|o| o.name == l.name) {
                return Err(err(format!("{f}.name"), "duplicate load region name"));
            }
        }
        for (k, p) in self.probes.iter().enumerate() {
            xml_text(&format!("probes[{k}].name"), &p.name, false)?;
            let f = format!("probes[{k}] ('{}')", p.name);
            vector(&format!("{f}.point"), &p.point, d)?;
            if self.probes[..k].iter().any(|o| o.name == p.name) {
                return Err(err(format!("{f}.name"), "duplicate probe name"));
            }
            if let Some(j) = self.loads.iter().position(|l| l.name == p.name) {
                let n = &p.name;
                return Err(err(
                    format!("{f}.name"),
                    format!(
                        "the load region loads[{j}] has the same name '{n}': an FMU names the \
                         outputs of both {n}.ux, {n}.uy, {n}.vx, ... (the probe's displacement and \
                         velocity, the load region's mean ones), so they would collide. Rename \
                         one of them, e.g. the probe to '{n}_probe' (its column in probes.csv and \
                         its FMU outputs follow), or the load region (its inputs {n}.fx/.fy/.fz \
                         follow)"
                    ),
                ));
            }
            let inside = |b: &Body| self.body_contains(b, &p.point);
            match &p.body {
                Some(name) => {
                    let bi = self.body_index(name).ok_or_else(|| {
                        err(format!("{f}.body"), format!("no body named '{name}'"))
                    })?;
                    if !inside(&self.bodies[bi]) {
                        return Err(err(
                            format!("{f}.point"),
                            format!("{:?} is outside body '{name}'", p.point),
                        ));
                    }
                }
                None => {
                    if !self.bodies.iter().any(inside) {
                        return Err(err(
                            format!("{f}.point"),
                            format!("{:?} is outside every body", p.point),
                        ));
                    }
                }
            }
        }
        if let Some(a) = &self.analysis {
            if !self.probes.iter().any(|p| p.name == a.probe) {
                return Err(err(
                    "analysis.probe",
                    format!("no probe named '{}'", a.probe),
                ));
            }
            if axis_index(&a.component).is_none_or(|i| i >= d) {
                return Err(err(
                    "analysis.component",
                    format!("'{}' is not an axis", a.component),
                ));
            }
        }
        Ok(())
    }

    /// Particles the boxes of all bodies hold before overlaps are dropped (an upper bound of the
    /// particle count; 0 for boxes that are not valid).
    pub fn particle_bound(&self) -> f64 {
        self.bodies
            .iter()
            .map(|b| self.body_particle_bound(b))
            .sum()
    }

    /// The particles the boxes of body `b` can hold (an upper bound, as `particle_bound`); for
    /// a body with shapes, the cells of the lattice over the bounds of its solid.
    pub fn body_particle_bound(&self, b: &Body) -> f64 {
        if !b.shapes.is_empty() || !b.cuts.is_empty() {
            return match self.geometry(b) {
                Ok(g) => fill::lattice_range(self, b, &g, self.dimension)
                    .map(|(_, n)| n.iter().map(|&k| k as f64).product())
                    .unwrap_or(f64::INFINITY),
                Err(_) => 0.0,
            };
        }
        b.boxes
            .iter()
            .filter_map(|r| self.cell_counts(r, "").ok())
            .map(|c| c.iter().map(|&n| n as f64).product::<f64>())
            .sum()
    }

    /// The solid of a body with shapes: its boxes and shapes less its cuts (meshes read).
    pub fn geometry(&self, b: &Body) -> Result<shape::Geometry, SceneError> {
        let d = self.dimension;
        let base = self.base_dir.as_deref();
        let k = self.body_index(&b.name).unwrap_or(0);
        let f = body_field(k, b);
        let mut parts: Vec<shape::Solid> = b
            .boxes
            .iter()
            .map(|r| shape::solid("", &Shape::Box(r.clone()), d, base))
            .collect::<Result<_, _>>()?;
        for (j, s) in b.shapes.iter().enumerate() {
            parts.push(shape::solid(&format!("{f}.shapes[{j}]"), s, d, base)?);
        }
        let cuts = b
            .cuts
            .iter()
            .enumerate()
            .map(|(j, s)| shape::solid(&format!("{f}.cuts[{j}]"), s, d, base))
            .collect::<Result<_, _>>()?;
        Ok(shape::Geometry { parts, cuts })
    }

    /// Whether a point (m) lies in body b: in one of its boxes (1e-9 m margin), or for a body
    /// with shapes in its solid (1e-6 l0 margin).
    pub fn body_contains(&self, b: &Body, p: &[f64]) -> bool {
        let d = self.dimension;
        if b.shapes.is_empty() && b.cuts.is_empty() {
            return b
                .boxes
                .iter()
                .any(|r| (0..d).all(|i| p[i] >= r.min[i] - 1e-9 && p[i] <= r.max[i] + 1e-9));
        }
        self.geometry(b)
            .is_ok_and(|g| g.distance(shape::to3(p)) <= 1e-6 * self.particle_spacing)
    }

    /// Checks the selection of a boundary group or load region (`f` names it): a region, a
    /// shape, or both.
    fn selection(&self, f: &str, r: &Region, s: Option<&Shape>) -> Result<(), SceneError> {
        let d = self.dimension;
        let open = r.min.is_empty() && r.max.is_empty();
        match s {
            Some(s) => {
                if !open {
                    region(&format!("{f}.region"), r, d)?;
                }
                shape::check(
                    &format!("{f}.shape"),
                    s,
                    d,
                    self.particle_spacing,
                    false,
                    self.base_dir.as_deref(),
                )?;
                Ok(())
            }
            None => region(&format!("{f}.region"), r, d),
        }
    }

    pub fn body_index(&self, name: &str) -> Option<usize> {
        self.bodies.iter().position(|b| b.name == name)
    }

    /// Number of particle cells along each axis of a body box.
    pub(crate) fn cell_counts(&self, r: &Region, field: &str) -> Result<Vec<usize>, SceneError> {
        region(field, r, self.dimension)?;
        let dp = self.particle_spacing;
        (0..self.dimension)
            .map(|k| {
                let len = r.max[k] - r.min[k];
                let n = (len / dp).round();
                if n < 1.0 || (n * dp - len).abs() > 1e-6 * dp {
                    return Err(err(field, format!("side {k} has length {} m, which is not a whole number (>= 1) of particle_spacing = {} m", num(len), num(dp))));
                }
                if n > 1e7 {
                    return Err(err(field, format!("side {k} holds {} particles, more than 1e7", num(n))));
                }
                Ok(n as usize)
            })
            .collect()
    }
}

/// A serde message in the words of a scene: the Rust type a number must fit ("expected usize")
/// becomes what to write ("expected a whole number, e.g. 3 (not 3.0)").
fn in_words(message: &str) -> String {
    let mut m = message.to_string();
    for ty in ["usize", "u64", "u32", "u8"] {
        m = m.replace(
            &format!("expected {ty}"),
            "expected a whole number, e.g. 3 (not 3.0)",
        );
    }
    m.replace("expected f64", "expected a number")
}

/// Longest scene file read (bytes): a scene is a few kB, this keeps a wrong file from being
/// read whole.
const MAX_SCENE_BYTES: u64 = 64 << 20;

/// The field path of body k in messages.
pub(crate) fn body_field(k: usize, b: &Body) -> String {
    format!("bodies[{k}] ('{}')", b.name.escape_debug())
}

/// Checks v against a `limits::Bound` that is "> 0" (the message says "positive finite").
fn positive(b: &limits::Bound, v: f64) -> Result<(), SceneError> {
    if b.contains(v) {
        Ok(())
    } else {
        Err(err(
            b.field,
            format!("must be a positive finite number, got {}", num(v)),
        ))
    }
}

/// Checks v against a `limits::Bound`: "must be in (1, 4], got 5", "must be >= 1, got 0".
fn bounded(b: &limits::Bound, v: f64) -> Result<(), SceneError> {
    if b.contains(v) {
        return Ok(());
    }
    let what = if b.min.is_some() && b.max.is_some() {
        format!("in {}", b.describe())
    } else {
        b.describe()
    };
    Err(err(b.field, format!("must be {what}, got {}", num(v))))
}

/// Checks v against a range of `limits`; the field is `prefix.range.field` (or the range's own
/// field when prefix is empty).
fn ranged(prefix: &str, r: &limits::Range, v: f64) -> Result<(), SceneError> {
    r.check(v).map_err(|m| {
        let field = if prefix.is_empty() {
            r.field.to_string()
        } else {
            format!("{prefix}.{}", r.field)
        };
        err(field, m)
    })
}

/// Text that goes into the modelDescription.xml: XML 1.0 allows no control character other than
/// tab, line feed and carriage return (not even escaped), nor U+FFFE and U+FFFF. Names take no
/// control character at all.
fn xml_text(field: &str, s: &str, multiline: bool) -> Result<(), SceneError> {
    let bad = s.chars().find(|&c| {
        let allowed_ws = multiline && matches!(c, '\t' | '\n' | '\r');
        (c.is_control() && (c as u32) < 0x20 && !allowed_ws)
            || (!multiline && c.is_control())
            || c == '\u{FFFE}'
            || c == '\u{FFFF}'
    });
    match bad {
        Some(c) => Err(err(
            field,
            format!(
                "contains the control character U+{:04X}, which an FMU's modelDescription.xml \
                 cannot hold{}",
                c as u32,
                if multiline {
                    " (only tab and line breaks are allowed)"
                } else {
                    ""
                }
            ),
        )),
        None => Ok(()),
    }
}

fn vector(field: &str, v: &[f64], d: usize) -> Result<(), SceneError> {
    if v.len() != d {
        return Err(err(
            field,
            format!("must have {d} components, got {}", v.len()),
        ));
    }
    if let Some(x) = v.iter().find(|x| !x.is_finite()) {
        return Err(err(field, format!("component {x} is not finite")));
    }
    Ok(())
}

fn region(field: &str, r: &Region, d: usize) -> Result<(), SceneError> {
    vector(&format!("{field}.min"), &r.min, d)?;
    vector(&format!("{field}.max"), &r.max, d)?;
    if (0..d).any(|k| r.max[k] < r.min[k]) {
        return Err(err(field, "max must not be below min"));
    }
    Ok(())
}
