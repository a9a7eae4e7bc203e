//! The one variable table of an FMU, derived from a scene: names, value references, types,
//! causality, variability, units, start values and what each variable means. It drives
//! `fmi2Get*`/`fmi2Set*` (through [`Quantity`]) and the modelDescription.xml.
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
            vars.push(Variable {
                name,
                value_reference,
                ty,
                causality,
                variability,
                unit,
                description,
                start,
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
                format!("Poisson's ratio of body '{}', in (-1, 0.5)", body.name),
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
            "Fixed solver time step; 0 = automatic (safety factor times the stability limit). \
             Each doStep is split into equal sub-steps no longer than this and lands exactly on t + h"
                .into(),
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
            "Critical bond strain eps_max of Eq. (42): a bond stretched beyond it breaks for good; \
             0 = no fracture"
                .into(),
            Some(scene.solver.fracture_strain.unwrap_or(0.0)),
            Quantity::FractureStrain,
        );
        // Inputs.
        let ramp = scene
            .gravity
            .paper_ramp_period
            .map(|t| format!(" (the scene ramps it up with Eq. (46), T = {t} s)"))
            .unwrap_or_default();
        for (k, axis) in AXES.iter().enumerate().take(d) {
            push(
                format!("gravity_{axis}"),
                Real,
                Input,
                Continuous,
                Some("m/s2"),
                format!(
                    "Gravity, {axis} component. Until the host sets a gravity component to a value \
                     other than the one it has, the scene's gravity law applies{ramp}; from then on \
                     the gravity vector is held constant at the values set"
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
                        "Displacement of probe '{}' at reference point {:?}, {axis} component",
                        probe.name, probe.point
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
                "Where gravity comes from: 1 = the scene's gravity law{ramp}, the inputs gravity_* \
                 are ignored (a warning is logged if they are set to other values); 2 = the inputs \
                 gravity_*, held over each step or linear with fmi2SetRealInputDerivatives. \
                 Default: 1 for a scene with a time law, else 2"
            ),
            Some(if scene.gravity.paper_ramp_period.is_some() {
                1.0
            } else {
                2.0
            }),
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
                        "Velocity of probe '{}' at reference point {:?}, {axis} component",
                        probe.name, probe.point
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

    /// Writes a parameter's value into a scene, checking its range. Returns an error message
    /// naming the problem.
    pub fn set_parameter(scene: &mut Scene, q: Quantity, v: f64) -> Result<(), String> {
        let positive = |what: &str| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(format!("{what} must be a positive finite number, got {v}"))
            }
        };
        match q {
            Quantity::Density(b) => {
                positive("density")?;
                body(scene, b)?.material.density = v;
            }
            Quantity::Young(b) => {
                positive("Young's modulus")?;
                body(scene, b)?.material.young = v;
            }
            Quantity::Poisson(b) => {
                if !(v.is_finite() && v > -1.0 && v < 0.5) {
                    return Err(format!("Poisson's ratio must be in (-1, 0.5), got {v}"));
                }
                body(scene, b)?.material.poisson = v;
            }
            Quantity::SolverDt => {
                if !(v.is_finite() && v >= 0.0) {
                    return Err(format!("solver.dt must be >= 0 (0 = automatic), got {v}"));
                }
                scene.solver.dt = (v > 0.0).then_some(v);
            }
            Quantity::Damping => {
                if !(v.is_finite() && v >= 0.0) {
                    return Err(format!("solver.damping must be >= 0, got {v}"));
                }
                scene.solver.damping = v;
            }
            Quantity::FractureStrain => {
                if !(v.is_finite() && v >= 0.0) {
                    return Err(format!(
                        "solver.fracture_strain must be >= 0 (0 = no fracture), got {v}"
                    ));
                }
                scene.solver.fracture_strain = (v > 0.0).then_some(v);
            }
            _ => return Err("not a parameter".into()),
        }
        Ok(())
    }
}

fn body(scene: &mut Scene, b: usize) -> Result<&mut crate::scene::Body, String> {
    scene
        .bodies
        .get_mut(b)
        .ok_or_else(|| format!("no body {b}"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cases::{case2_scene, Support};
    use crate::physics::ElasticModel;

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
        };
        s.loads = vec![l.clone(), l];
        let t = VariableTable::new(&s);
        assert!(t.by_name("tip.fz").is_some());
        assert!(t.by_name("tip.fz_2").is_some());
    }
}
