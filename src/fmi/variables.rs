//! The one variable table of an FMU, derived from a scene: names, value references, types,
//! causality, variability, units, start values and what each variable means. It drives
//! `fmi2Get*`/`fmi2Set*` (through [`Quantity`]) and the modelDescription.xml.
use crate::scene::limits::{self, Range};
use crate::scene::Scene;

/// FMI base type of a variable.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VarType {
    Real,
    Integer,
}

impl VarType {
    pub fn name(self) -> &'static str {
        match self {
            VarType::Real => "Real",
            VarType::Integer => "Integer",
        }
    }
}

/// FMI causality (only those this FMU uses).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Causality {
    Parameter,
    Input,
    Output,
}

impl Causality {
    pub fn name(self) -> &'static str {
        match self {
            Causality::Parameter => "parameter",
            Causality::Input => "input",
            Causality::Output => "output",
        }
    }
}

/// FMI variability (only those this FMU uses).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Variability {
    Fixed,
    Discrete,
    Continuous,
}

impl Variability {
    pub fn name(self) -> &'static str {
        match self {
            Variability::Fixed => "fixed",
            Variability::Discrete => "discrete",
            Variability::Continuous => "continuous",
        }
    }
}

/// What a variable stands for; indices are into the scene's lists, `axis` is 0, 1 or 2.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Quantity {
    /// Parameter: density of body b (kg/m3).
    Density(usize),
    /// Parameter: Young's modulus of body b (Pa).
    Young(usize),
    /// Parameter: Poisson's ratio of body b (-).
    Poisson(usize),
    /// Parameter: fixed solver time step (s), 0 = automatic.
    SolverDt,
    /// Parameter: mass-proportional damping (1/s).
    Damping,
    /// Parameter: critical bond strain eps_max of Eq. (42) (-), 0 = no fracture.
    FractureStrain,
    /// Input: gravity component (m/s2).
    Gravity(usize),
    /// Input: prescribed displacement of boundary group g (m).
    GroupDisplacement(usize, usize),
    /// Input: total force on load region r (N).
    Load(usize, usize),
    /// Output: displacement of probe k (m).
    ProbeDisplacement(usize, usize),
    /// Output: broken bonds (Integer).
    FractureCount,
    /// Output: reaction force of boundary group g (N).
    Reaction(usize, usize),
    /// Output: kinetic energy (J).
    KineticEnergy,
    /// Output: strain energy (J).
    StrainEnergy,
    /// Output: solver steps taken (Integer).
    Steps,
    /// Output: strain energy released by broken bonds so far (J).
    FractureEnergy,
    /// Output: velocity of probe k (m/s).
    ProbeVelocity(usize, usize),
    /// Output: mean displacement of the particles of load region r (m).
    LoadDisplacement(usize, usize),
    /// Output: mean velocity of the particles of load region r (m/s).
    LoadVelocity(usize, usize),
    /// Parameter (Integer): 1 = the scene's gravity law, 2 = gravity from the inputs.
    GravitySource,
    /// Parameter (Integer): 1 = a boundary displacement input acts at the start of the step
    /// (FMI semantics), 2 = it is reached at the end of the step.
    BoundaryTiming,
}

/// One ScalarVariable.
#[derive(Clone, Debug, PartialEq)]
pub struct Variable {
    pub name: String,
    pub value_reference: u32,
    pub ty: VarType,
    pub causality: Causality,
    pub variability: Variability,
    pub unit: Option<&'static str>,
    pub description: String,
    /// Start value (parameters and inputs only; outputs are initial="calculated").
    pub start: Option<f64>,
    /// Smallest and largest value a parameter accepts (`min`/`max` in the XML; from
    /// `scene::limits`).
    pub min: Option<f64>,
    pub max: Option<f64>,
    pub quantity: Quantity,
}

impl Variable {
    /// The `initial` attribute written to the XML, if any.
    pub fn initial(&self) -> Option<&'static str> {
        match self.causality {
            Causality::Output => Some("calculated"),
            _ => None,
        }
    }
}

/// A unit of the UnitDefinitions: name and SI base-unit exponents (kg, m, s).
pub struct UnitDef {
    pub name: &'static str,
    pub kg: i32,
    pub m: i32,
    pub s: i32,
}

/// Every unit a variable may carry.
pub const UNITS: [UnitDef; 9] = [
    UnitDef {
        name: "m",
        kg: 0,
        m: 1,
        s: 0,
    },
    UnitDef {
        name: "m/s",
        kg: 0,
        m: 1,
        s: -1,
    },
    UnitDef {
        name: "N",
        kg: 1,
        m: 1,
        s: -2,
    },
    UnitDef {
        name: "J",
        kg: 1,
        m: 2,
        s: -2,
    },
    UnitDef {
        name: "s",
        kg: 0,
        m: 0,
        s: 1,
    },
    UnitDef {
        name: "m/s2",
        kg: 0,
        m: 1,
        s: -2,
    },
    UnitDef {
        name: "kg/m3",
        kg: 1,
        m: -3,
        s: 0,
    },
    UnitDef {
        name: "Pa",
        kg: 1,
        m: -1,
        s: -2,
    },
    UnitDef {
        name: "1/s",
        kg: 0,
        m: 0,
        s: -1,
    },
];

const AXES: [&str; 3] = ["x", "y", "z"];

/// Values of the Integer parameter gravity_source (`instance::GravitySource`): gravity from the
/// scene's law, or from the inputs gravity_*.
pub const GRAVITY_FROM_SCENE: i32 = 1;
pub const GRAVITY_FROM_INPUTS: i32 = 2;

/// A coordinate for a text: rounded to 12 significant digits, then the shortest form that
/// reads back to the rounded value (0.48750000000000004 reads "0.4875"). 12 digits resolve a
/// position to 1e-12 of its size, far below the 2^-20 of the particle spacing that positions
/// keep (`physics::world::build::MIN_SPACING_BITS`).
pub fn coordinate(v: f64) -> String {
    let rounded = format!("{v:.11e}").parse::<f64>().unwrap_or(v);
    limits::num(rounded)
}

/// A point for a text: "(x, y, z)" of [`coordinate`]s.
pub fn point(p: &[f64]) -> String {
    let c: Vec<String> = p.iter().map(|&v| coordinate(v)).collect();
    format!("({})", c.join(", "))
}

/// The range of a parameter as its description quotes it: the declared [min, max] (the XML's
/// `min`/`max`, the page's range column), and for a parameter whose 0 means "off" what 0
/// means and the smallest other value.
pub fn describe_range(q: Quantity) -> String {
    let Some((r, off)) = parameter_range(q) else {
        return String::new();
    };
    let unit = if r.unit.is_empty() {
        String::new()
    } else {
        format!(" {}", r.unit)
    };
    if off {
        format!(
            "in [0, {}]{unit} (0 = {}; otherwise at least {}{unit})",
            limits::num(r.max),
            off_meaning(q),
            limits::num(r.min)
        )
    } else {
        format!("in {}", r.describe())
    }
}

/// What 0 means for a parameter that accepts it besides its range.
fn off_meaning(q: Quantity) -> &'static str {
    if q == Quantity::SolverDt {
        "automatic"
    } else {
        "no fracture"
    }
}

/// The variable table of a scene.
#[derive(Clone, Debug, PartialEq)]
pub struct VariableTable {
    pub vars: Vec<Variable>,
}

/// A name part under the "structured" naming convention: an identifier as is, anything else
/// quoted (characters a q-name cannot hold become '_').
pub fn name_part(s: &str) -> String {
    let ident = !s.is_empty()
        && s.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
        && !s.starts_with(|c: char| c.is_ascii_digit());
    if ident {
        return s.to_string();
    }
    const QCHARS: &str = "!#$%&()*+,-./:;<=>?@[]^{}|~ _";
    let inner: String = s
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || QCHARS.contains(c) {
                c
            } else {
                '_'
            }
        })
        .collect();
    if inner.is_empty() {
        "'_'".into()
    } else {
        format!("'{inner}'")
    }
}

impl VariableTable {
    /// Builds the table of a (validated) scene.
    pub fn new(scene: &Scene) -> Self {
        let d = scene.dimension.clamp(2, 3);
        let mut vars: Vec<Variable> = Vec::new();
        let mut push = |name: String,
                        ty: VarType,
                        causality: Causality,
                        variability: Variability,
                        unit: Option<&'static str>,
                        description: String,
                        start: Option<f64>,
                        quantity: Quantity| {
            let value_reference = vars.len() as u32;
            let bounds = match quantity {
                Quantity::GravitySource => Some((
                    f64::from(GRAVITY_FROM_SCENE),
                    f64::from(GRAVITY_FROM_INPUTS),
                )),
                Quantity::BoundaryTiming => Some((1.0, 2.0)),
                _ => parameter_range(quantity).map(|(r, off)| {
                    let min = if off { 0.0 } else { r.min };
                    (min, r.max)
                }),
            };
            vars.push(Variable {
                name,
                value_reference,
                ty,
                causality,
                variability,
                unit,
                description,
                start,
                min: bounds.map(|b| b.0),
                max: bounds.map(|b| b.1),
                quantity,
            });
        };
        use Causality::*;
        use VarType::*;
        use Variability::*;
        // Parameters.
        for (b, body) in scene.bodies.iter().enumerate() {
            let n = name_part(&body.name);
            let m = &body.material;
            push(
                format!("{n}.density"),
                Real,
                Parameter,
                Fixed,
                Some("kg/m3"),
                format!("Density of body '{}'", body.name),
                Some(m.density),
                Quantity::Density(b),
            );
            push(
                format!("{n}.young"),
                Real,
                Parameter,
                Fixed,
                Some("Pa"),
                format!("Young's modulus of body '{}'", body.name),
                Some(m.young),
                Quantity::Young(b),
            );
            push(
                format!("{n}.poisson"),
                Real,
                Parameter,
                Fixed,
                None,
                format!(
                    "Poisson's ratio of body '{}', {}",
                    body.name,
                    describe_range(Quantity::Poisson(b))
                ),
                Some(m.poisson),
                Quantity::Poisson(b),
            );
        }
        push(
            "solver.dt".into(),
            Real,
            Parameter,
            Fixed,
            Some("s"),
            format!(
                "Fixed solver time step, {}. Automatic: the safety factor times the stability \
                 limit. Each doStep is split into equal sub-steps no longer than this and lands \
                 exactly on t + h",
                describe_range(Quantity::SolverDt)
            ),
            Some(scene.solver.dt.unwrap_or(0.0)),
            Quantity::SolverDt,
        );
        push(
            "solver.damping".into(),
            Real,
            Parameter,
            Fixed,
            Some("1/s"),
            "Mass-proportional damping coefficient c (force -c m v on each particle); 0 = off"
                .into(),
            Some(scene.solver.damping),
            Quantity::Damping,
        );
        push(
            "solver.fracture_strain".into(),
            Real,
            Parameter,
            Fixed,
            None,
            format!(
                "Critical bond strain eps_max of Eq. (42), {}: a bond stretched beyond it breaks \
                 for good",
                describe_range(Quantity::FractureStrain)
            ),
            Some(scene.solver.fracture_strain.unwrap_or(0.0)),
            Quantity::FractureStrain,
        );
        // Inputs.
        let ramp = scene
            .gravity
            .paper_ramp_period
            .map(|t| {
                format!(
                    " (the scene ramps it up with Eq. (46), T = {} s)",
                    limits::num(t)
                )
            })
            .unwrap_or_default();
        for (k, axis) in AXES.iter().enumerate().take(d) {
            push(
                format!("gravity_{axis}"),
                Real,
                Input,
                Continuous,
                Some("m/s2"),
                format!(
                    "Gravity, {axis} component. Acts when gravity_source = {inputs}: held over each \
                     step, or linear with its input derivative. Ignored when gravity_source = \
                     {scene_law}: the scene's gravity law applies{ramp} (a warning is logged if it \
                     is set to another value)",
                    inputs = GRAVITY_FROM_INPUTS,
                    scene_law = GRAVITY_FROM_SCENE
                ),
                Some(scene.gravity.vector.get(k).copied().unwrap_or(0.0)),
                Quantity::Gravity(k),
            );
        }
        for (g, group) in scene.boundaries.iter().enumerate() {
            let n = name_part(&group.name);
            for (k, axis) in AXES.iter().enumerate().take(d) {
                push(
                    format!("{n}.d{axis}"),
                    Real,
                    Input,
                    Continuous,
                    Some("m"),
                    format!(
                        "Prescribed displacement of boundary group '{}', {axis} component (acts on \
                         the group's held axes only). When it acts is set by boundary_input_timing \
                         (default: at the start of the step, held or extrapolated)",
                        group.name
                    ),
                    Some(0.0),
                    Quantity::GroupDisplacement(g, k),
                );
            }
        }
        for (r, load) in scene.loads.iter().enumerate() {
            let n = name_part(&load.name);
            for (k, axis) in AXES.iter().enumerate().take(d) {
                push(
                    format!("{n}.f{axis}"),
                    Real,
                    Input,
                    Continuous,
                    Some("N"),
                    format!(
                        "Total external force on load region '{}', {axis} component, spread evenly \
                         over its particles; held over each step, or linear with its input derivative",
                        load.name
                    ),
                    Some(0.0),
                    Quantity::Load(r, k),
                );
            }
        }
        // Outputs.
        for (p, probe) in scene.probes.iter().enumerate() {
            let n = name_part(&probe.name);
            for (k, axis) in AXES.iter().enumerate().take(d) {
                push(
                    format!("{n}.u{axis}"),
                    Real,
                    Output,
                    Continuous,
                    Some("m"),
                    format!(
                        "Displacement of probe '{}' at reference point {} m, {axis} component",
                        probe.name,
                        point(&probe.point)
                    ),
                    None,
                    Quantity::ProbeDisplacement(p, k),
                );
            }
        }
        push(
            "fracture_count".into(),
            Integer,
            Output,
            Discrete,
            None,
            "Number of broken bonds (each particle pair counted once)".into(),
            None,
            Quantity::FractureCount,
        );
        for (g, group) in scene.boundaries.iter().enumerate() {
            let n = name_part(&group.name);
            for (k, axis) in AXES.iter().enumerate().take(d) {
                push(
                    format!("{n}.reaction_{axis}"),
                    Real,
                    Output,
                    Continuous,
                    Some("N"),
                    format!(
                        "Reaction force of boundary group '{}' on the body, {axis} component \
                         (0 along axes the group does not hold)",
                        group.name
                    ),
                    None,
                    Quantity::Reaction(g, k),
                );
            }
        }
        push(
            "kinetic_energy".into(),
            Real,
            Output,
            Continuous,
            Some("J"),
            "Kinetic energy of translation and rotation of all particles".into(),
            None,
            Quantity::KineticEnergy,
        );
        push(
            "strain_energy".into(),
            Real,
            Output,
            Continuous,
            Some("J"),
            "Elastic strain energy".into(),
            None,
            Quantity::StrainEnergy,
        );
        push(
            "steps".into(),
            Integer,
            Output,
            Discrete,
            None,
            "Solver time steps taken since the start".into(),
            None,
            Quantity::Steps,
        );
        // FMU settings (Integer parameters), last so that the value references above stay put.
        push(
            "gravity_source".into(),
            Integer,
            Parameter,
            Fixed,
            None,
            format!(
                "Where gravity comes from: {scene_law} = the scene's gravity law{ramp}, the inputs \
                 gravity_* are ignored (a warning is logged if they are set to other values); \
                 {inputs} = the inputs gravity_*, held over each step or linear with \
                 fmi2SetRealInputDerivatives. Default: {scene_law} for a scene with a time law, \
                 else {inputs}",
                inputs = GRAVITY_FROM_INPUTS,
                scene_law = GRAVITY_FROM_SCENE
            ),
            Some(f64::from(if scene.gravity.paper_ramp_period.is_some() {
                GRAVITY_FROM_SCENE
            } else {
                GRAVITY_FROM_INPUTS
            })),
            Quantity::GravitySource,
        );
        push(
            "boundary_input_timing".into(),
            Integer,
            Parameter,
            Fixed,
            None,
            "When a boundary displacement input set before doStep(t, h) acts: 1 = at t, held over \
             the step or extrapolated with its derivative (FMI 2.0 semantics, what generic masters \
             expect); 2 = it is reached at t + h, moving linearly from where the group is (smooth, \
             but one communication step behind the master's signal)"
                .into(),
            Some(1.0),
            Quantity::BoundaryTiming,
        );
        // Coupling outputs (after the settings, so that earlier value references stay put).
        for (p, probe) in scene.probes.iter().enumerate() {
            let n = name_part(&probe.name);
            for (k, axis) in AXES.iter().enumerate().take(d) {
                push(
                    format!("{n}.v{axis}"),
                    Real,
                    Output,
                    Continuous,
                    Some("m/s"),
                    format!(
                        "Velocity of probe '{}' at reference point {} m, {axis} component",
                        probe.name,
                        point(&probe.point)
                    ),
                    None,
                    Quantity::ProbeVelocity(p, k),
                );
            }
        }
        for (r, load) in scene.loads.iter().enumerate() {
            let n = name_part(&load.name);
            for (k, axis) in AXES.iter().enumerate().take(d) {
                push(
                    format!("{n}.u{axis}"),
                    Real,
                    Output,
                    Continuous,
                    Some("m"),
                    format!(
                        "Mean displacement of the particles load region '{}' acts on, {axis} \
                         component: the motion work-conjugate to its force input",
                        load.name
                    ),
                    None,
                    Quantity::LoadDisplacement(r, k),
                );
            }
            for (k, axis) in AXES.iter().enumerate().take(d) {
                push(
                    format!("{n}.v{axis}"),
                    Real,
                    Output,
                    Continuous,
                    Some("m/s"),
                    format!(
                        "Mean velocity of the particles load region '{}' acts on, {axis} component",
                        load.name
                    ),
                    None,
                    Quantity::LoadVelocity(r, k),
                );
            }
        }
        // Energy budget of fracture (after the coupling outputs: earlier value references stay
        // put).
        push(
            "fracture_energy".into(),
            Real,
            Output,
            Continuous,
            Some("J"),
            "Strain energy released by broken bonds so far: at each break, what the particles \
             that lost bonds held just before less what they hold after (never negative; \
             kinetic + strain + contact + fracture_energy is conserved without damping, loads \
             and gravity; per metre of depth in 2D; 0 for the paper's operators)"
                .into(),
            None,
            Quantity::FractureEnergy,
        );
        // Scene names are unique per kind (loads excepted); should two variables still share a
        // name, the later ones get a suffix so that the table is always valid.
        let mut seen = std::collections::HashSet::new();
        for v in &mut vars {
            let base = v.name.clone();
            let mut k = 2;
            while !seen.insert(v.name.clone()) {
                v.name = format!("{base}_{k}");
                k += 1;
            }
        }
        VariableTable { vars }
    }

    /// The variable of a value reference.
    pub fn get(&self, vr: u32) -> Option<&Variable> {
        self.vars.get(vr as usize)
    }

    /// The variable of a name.
    pub fn by_name(&self, name: &str) -> Option<&Variable> {
        self.vars.iter().find(|v| v.name == name)
    }

    /// 1-based indices (ModelStructure) of the outputs.
    pub fn output_indices(&self) -> Vec<usize> {
        self.vars
            .iter()
            .enumerate()
            .filter(|(_, v)| v.causality == Causality::Output)
            .map(|(i, _)| i + 1)
            .collect()
    }

    /// Reads a parameter's value from a scene.
    pub fn parameter_value(scene: &Scene, q: Quantity) -> Option<f64> {
        Some(match q {
            Quantity::Density(b) => scene.bodies.get(b)?.material.density,
            Quantity::Young(b) => scene.bodies.get(b)?.material.young,
            Quantity::Poisson(b) => scene.bodies.get(b)?.material.poisson,
            Quantity::SolverDt => scene.solver.dt.unwrap_or(0.0),
            Quantity::Damping => scene.solver.damping,
            Quantity::FractureStrain => scene.solver.fracture_strain.unwrap_or(0.0),
            _ => return None,
        })
    }

    /// Writes a parameter's value into a scene, checking its range (`scene::limits`, the same
    /// ranges and message as the scene validation). Returns an error message naming the field.
    pub fn set_parameter(scene: &mut Scene, q: Quantity, v: f64) -> Result<(), String> {
        let (range, off) = parameter_range(q).ok_or("not a parameter")?;
        let field = match q {
            Quantity::Density(b) | Quantity::Young(b) | Quantity::Poisson(b) => format!(
                "{}.{}",
                crate::scene::body_field(b, body(scene, b)?),
                range.field
            ),
            _ => range.field.to_string(),
        };
        if !(range.contains(v) || (off && v == 0.0)) {
            let msg = range.check(v).err().unwrap_or_default();
            return Err(match off {
                false => format!("{field}: {msg}"),
                true => format!("{field}: {msg} (or 0 = {})", off_meaning(q)),
            });
        }
        match q {
            Quantity::Density(b) => body(scene, b)?.material.density = v,
            Quantity::Young(b) => body(scene, b)?.material.young = v,
            Quantity::Poisson(b) => body(scene, b)?.material.poisson = v,
            Quantity::SolverDt => scene.solver.dt = (v != 0.0).then_some(v),
            Quantity::Damping => scene.solver.damping = v,
            Quantity::FractureStrain => scene.solver.fracture_strain = (v != 0.0).then_some(v),
            _ => return Err("not a parameter".into()),
        }
        Ok(())
    }
}

/// The range of a parameter (`scene::limits`) and whether 0 is accepted besides it (meaning
/// "automatic" for solver.dt, "no fracture" for solver.fracture_strain). None: not a parameter.
pub fn parameter_range(q: Quantity) -> Option<(Range, bool)> {
    Some(match q {
        Quantity::Density(_) => (limits::DENSITY, false),
        Quantity::Young(_) => (limits::YOUNG, false),
        Quantity::Poisson(_) => (limits::POISSON, false),
        Quantity::SolverDt => (limits::SOLVER_DT, true),
        Quantity::Damping => (limits::DAMPING, false),
        Quantity::FractureStrain => (limits::FRACTURE_STRAIN, true),
        _ => return None,
    })
}

impl VariableTable {}

fn body(scene: &mut Scene, b: usize) -> Result<&mut crate::scene::Body, String> {
    scene
        .bodies
        .get_mut(b)
        .ok_or_else(|| format!("no body {b}"))
}

// The scene builders of the paper's cases are study code (feature `studies`).
#[cfg(all(test, feature = "studies"))]
mod range_tests {
    use super::*;
    use crate::physics::ElasticModel;
    use crate::studies::cases::case1_scene;

    #[test]
    fn set_parameter_refuses_what_validation_refuses() {
        let s = case1_scene(0.05, ElasticModel::Corrected, None);
        let t = VariableTable::new(&s);
        let cases = [
            ("column.density", 1e-30, "material.density"),
            ("column.young", 1e30, "material.young"),
            ("column.poisson", 0.49999999999999994, "material.poisson"),
            ("solver.dt", 1e-30, "solver.dt"),
            ("solver.damping", -1.0, "solver.damping"),
            ("solver.fracture_strain", 1e3, "solver.fracture_strain"),
        ];
        for (name, v, field) in cases {
            let var = t.by_name(name).unwrap_or_else(|| panic!("{name}"));
            let mut sc = s.clone();
            let e = VariableTable::set_parameter(&mut sc, var.quantity, v).unwrap_err();
            assert!(e.contains(field) && e.contains("must be in"), "{name}: {e}");
            assert_eq!(sc, s, "{name}: nothing set");
            // The same value in the scene file is refused by the validation with the same text.
            let mut bad = s.clone();
            VariableTable::set_unchecked(&mut bad, var.quantity, v);
            let ve = bad.validate().unwrap_err().to_string();
            let msg = e
                .split(": ")
                .nth(1)
                .unwrap()
                .split(" (or 0")
                .next()
                .unwrap();
            assert!(ve.contains(msg), "{name}: '{ve}' vs '{e}'");
            // Bounds are declared and the start value lies within them.
            let (lo, hi) = (var.min.unwrap(), var.max.unwrap());
            assert!(
                lo <= var.start.unwrap() && var.start.unwrap() <= hi,
                "{name}"
            );
            // (solver.dt and fracture_strain also take 0 = off, so their declared min is 0.)
            let off = parameter_range(var.quantity).unwrap().1;
            assert!(off || !(lo..=hi).contains(&v), "{name}");
        }
        let mut sc = s.clone();
        let dt = t.by_name("solver.dt").unwrap().quantity;
        VariableTable::set_parameter(&mut sc, dt, 0.0).unwrap();
        assert_eq!(sc.solver.dt, None);
        VariableTable::set_parameter(&mut sc, dt, 1e-5).unwrap();
        assert_eq!(sc.solver.dt, Some(1e-5));
    }

    impl VariableTable {
        fn set_unchecked(scene: &mut Scene, q: Quantity, v: f64) {
            match q {
                Quantity::Density(b) => scene.bodies[b].material.density = v,
                Quantity::Young(b) => scene.bodies[b].material.young = v,
                Quantity::Poisson(b) => scene.bodies[b].material.poisson = v,
                Quantity::SolverDt => scene.solver.dt = Some(v),
                Quantity::Damping => scene.solver.damping = v,
                Quantity::FractureStrain => scene.solver.fracture_strain = Some(v),
                _ => unreachable!(),
            }
        }
    }
}

// The scene builders of the paper's cases are study code (feature `studies`).
#[cfg(all(test, feature = "studies"))]
mod tests {
    use super::*;
    use crate::physics::ElasticModel;
    use crate::studies::cases::{case2_scene, Support};

    #[test]
    fn case2_table() {
        let s = case2_scene(0.05, ElasticModel::Corrected, None, Support::Face);
        let t = VariableTable::new(&s);
        for (i, v) in t.vars.iter().enumerate() {
            assert_eq!(v.value_reference as usize, i);
            assert_eq!(
                v.start.is_some(),
                v.causality != Causality::Output,
                "{}",
                v.name
            );
        }
        assert!(t.by_name("beam.young").is_some());
        assert!(t.by_name("clamp.dz").is_some());
        assert!(t.by_name("support.reaction_y").is_some());
        assert!(t.by_name("max.uz").is_some());
        assert_eq!(t.by_name("gravity_z").unwrap().start, Some(-9.81));
        assert_eq!(t.by_name("steps").unwrap().ty, VarType::Integer);
    }

    #[test]
    fn names() {
        assert_eq!(name_part("abc_1"), "abc_1");
        assert_eq!(name_part("1abc"), "'1abc'");
        assert_eq!(name_part("a b\"c"), "'a b_c'");
    }

    #[test]
    fn duplicate_names_get_a_suffix() {
        let mut s = case2_scene(0.05, ElasticModel::Corrected, None, Support::Face);
        let l = crate::scene::LoadSpec {
            name: "tip".into(),
            body: "beam".into(),
            region: s.boundaries[1].region.clone(),
            shape: None,
        };
        s.loads = vec![l.clone(), l];
        let t = VariableTable::new(&s);
        assert!(t.by_name("tip.fz").is_some());
        assert!(t.by_name("tip.fz_2").is_some());
    }
}
