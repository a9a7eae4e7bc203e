//! modelDescription.xml of a scene's FMU, written with quick-xml from the variable table, and the
//! GUID: a deterministic UUID-formatted hash of the scene and the crate version.
use super::variables::{Causality, Quantity, VarType, VariableTable, UNITS};
use crate::scene::Scene;
use quick_xml::events::{BytesDecl, BytesEnd, BytesStart, Event};
use quick_xml::Writer;

/// Log categories understood by `fmi2SetDebugLogging` (name, description).
pub const LOG_CATEGORIES: [(&str, &str); 4] = [
    ("logStatusError", "Calls that return fmi2Error or fmi2Fatal"),
    (
        "logStatusWarning",
        "Calls that return fmi2Warning or fmi2Discard",
    ),
    (
        "logEvents",
        "Instantiation, mode changes, parameter rebuilds, FMU state operations",
    ),
    (
        "logAll",
        "The events and a line per fmi2DoStep with its solver sub-steps",
    ),
];

/// 128-bit FNV-1a.
fn fnv1a128(data: &[u8]) -> u128 {
    let mut h: u128 = 0x6c62272e07bb014262b821756295c58d;
    for &b in data {
        h ^= b as u128;
        h = h.wrapping_mul(0x0000000001000000000000000000013B);
    }
    h
}

/// The GUID of a scene's FMU: a hash of the scene's JSON and the crate version, formatted as a
/// UUID (version 8, i.e. custom) in braces.
pub fn guid(scene: &Scene) -> String {
    let text = format!("{}\n{}", scene.to_json(), env!("CARGO_PKG_VERSION"));
    let mut h = fnv1a128(text.as_bytes()).to_be_bytes();
    h[6] = (h[6] & 0x0f) | 0x80;
    h[8] = (h[8] & 0x3f) | 0x80;
    let hex: String = h.iter().map(|b| format!("{b:02x}")).collect();
    format!(
        "{{{}-{}-{}-{}-{}}}",
        &hex[0..8],
        &hex[8..12],
        &hex[12..16],
        &hex[16..20],
        &hex[20..32]
    )
}

/// Formats a Real so that it reads back to the same f64 (shortest round-trip form).
pub fn real(v: f64) -> String {
    format!("{v:?}")
}

struct Xml {
    w: Writer<Vec<u8>>,
}

impl Xml {
    fn start(&mut self, name: &str, attrs: &[(&str, &str)], empty: bool) {
        let mut e = BytesStart::new(name);
        for (k, v) in attrs {
            e.push_attribute((*k, *v));
        }
        let ev = if empty {
            Event::Empty(e)
        } else {
            Event::Start(e)
        };
        self.w.write_event(ev).expect("writing to a Vec");
    }
    fn end(&mut self, name: &str) {
        self.w
            .write_event(Event::End(BytesEnd::new(name)))
            .expect("writing to a Vec");
    }
}

/// The modelDescription.xml of a scene's FMU.
pub fn model_description_xml(scene: &Scene) -> String {
    let table = VariableTable::new(scene);
    let mut x = Xml {
        w: Writer::new_with_indent(Vec::new(), b' ', 2),
    };
    x.w.write_event(Event::Decl(BytesDecl::new("1.0", Some("UTF-8"), None)))
        .expect("writing to a Vec");
    let guid = guid(scene);
    let description = if scene.description.is_empty() {
        format!("MPS elastic-solid simulation of scene '{}'", scene.name)
    } else {
        scene.description.clone()
    };
    let tool = format!("mps-solid {}", env!("CARGO_PKG_VERSION"));
    x.start(
        "fmiModelDescription",
        &[
            ("fmiVersion", "2.0"),
            ("modelName", &scene.name),
            ("guid", &guid),
            ("description", &description),
            ("generationTool", &tool),
            ("variableNamingConvention", "structured"),
            ("numberOfEventIndicators", "0"),
        ],
        false,
    );
    x.start(
        "CoSimulation",
        &[
            ("modelIdentifier", &scene.name),
            ("canHandleVariableCommunicationStepSize", "true"),
            ("canInterpolateInputs", "true"),
            ("canGetAndSetFMUstate", "true"),
            ("canSerializeFMUstate", "true"),
        ],
        true,
    );
    x.start("UnitDefinitions", &[], false);
    for u in &UNITS {
        x.start("Unit", &[("name", u.name)], false);
        let (kg, m, s) = (u.kg.to_string(), u.m.to_string(), u.s.to_string());
        let mut attrs: Vec<(&str, &str)> = Vec::new();
        if u.kg != 0 {
            attrs.push(("kg", &kg));
        }
        if u.m != 0 {
            attrs.push(("m", &m));
        }
        if u.s != 0 {
            attrs.push(("s", &s));
        }
        x.start("BaseUnit", &attrs, true);
        x.end("Unit");
    }
    x.end("UnitDefinitions");
    x.start("LogCategories", &[], false);
    for (name, desc) in LOG_CATEGORIES {
        x.start("Category", &[("name", name), ("description", desc)], true);
    }
    x.end("LogCategories");
    let (stop, step) = (real(scene.end_time), real(scene.output_interval));
    x.start(
        "DefaultExperiment",
        &[
            ("startTime", "0.0"),
            ("stopTime", &stop),
            ("stepSize", &step),
        ],
        true,
    );
    x.start("ModelVariables", &[], false);
    for (i, v) in table.vars.iter().enumerate() {
        x.w.write_event(Event::Comment(quick_xml::events::BytesText::new(&format!(
            " index {} ",
            i + 1
        ))))
        .expect("writing to a Vec");
        let vr = v.value_reference.to_string();
        let mut attrs: Vec<(&str, &str)> = vec![
            ("name", &v.name),
            ("valueReference", &vr),
            ("description", &v.description),
            ("causality", v.causality.name()),
            ("variability", v.variability.name()),
        ];
        if let Some(init) = v.initial() {
            attrs.push(("initial", init));
        }
        x.start("ScalarVariable", &attrs, false);
        let start = v.start.map(|s| match v.ty {
            VarType::Real => real(s),
            VarType::Integer => (s as i64).to_string(),
        });
        let mut ta: Vec<(&str, &str)> = Vec::new();
        if let (VarType::Real, Some(u)) = (v.ty, v.unit) {
            ta.push(("unit", u));
        }
        if let Some(s) = &start {
            ta.push(("start", s));
        }
        // Parameters declare the range they accept (scene::limits).
        let (min, max) = (v.min.map(real), v.max.map(real));
        if let (VarType::Real, Causality::Parameter) = (v.ty, v.causality) {
            if let Some(m) = &min {
                ta.push(("min", m));
            }
            if let Some(m) = &max {
                ta.push(("max", m));
            }
        }
        x.start(v.ty.name(), &ta, true);
        x.end("ScalarVariable");
    }
    x.end("ModelVariables");
    x.start("ModelStructure", &[], false);
    let outputs = table.output_indices();
    x.start("Outputs", &[], false);
    for i in &outputs {
        x.start("Unknown", &[("index", &i.to_string())], true);
    }
    x.end("Outputs");
    // At initialisation the outputs describe the undeformed reference state at t = 0: probe
    // displacements, broken bonds and steps are 0 whatever the parameters and inputs; the
    // reactions and the strain energy are 0 up to round-off that scales with the elastic
    // constants; the kinetic energy depends on the densities of the bodies that start moving.
    x.start("InitialUnknowns", &[], false);
    for i in &outputs {
        let v = &table.vars[i - 1];
        let moving = |b: usize| {
            scene.bodies[b]
                .velocity
                .as_ref()
                .is_some_and(|vel| vel.iter().any(|c| *c != 0.0))
        };
        let depends = |p: Quantity| match (v.quantity, p) {
            (Quantity::KineticEnergy, Quantity::Density(b)) => moving(b),
            (
                Quantity::Reaction(..) | Quantity::StrainEnergy,
                Quantity::Young(_) | Quantity::Poisson(_),
            ) => true,
            _ => false,
        };
        let deps: Vec<String> = table
            .vars
            .iter()
            .enumerate()
            .filter(|(_, p)| depends(p.quantity))
            .map(|(j, _)| (j + 1).to_string())
            .collect();
        debug_assert_eq!(v.causality, Causality::Output);
        let deps = deps.join(" ");
        x.start(
            "Unknown",
            &[("index", &i.to_string()), ("dependencies", &deps)],
            true,
        );
    }
    x.end("InitialUnknowns");
    x.end("ModelStructure");
    x.end("fmiModelDescription");
    let mut s = String::from_utf8(x.w.into_inner()).expect("quick-xml writes UTF-8");
    s.push('\n');
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cases::case1_scene;
    use crate::physics::ElasticModel;

    #[test]
    fn guid_is_deterministic_and_scene_specific() {
        let a = case1_scene(0.05, ElasticModel::Corrected, None);
        let mut b = a.clone();
        assert_eq!(guid(&a), guid(&b));
        b.bodies[0].material.young *= 2.0;
        assert_ne!(guid(&a), guid(&b));
        let g = guid(&a);
        assert_eq!(g.len(), 38);
        assert_eq!(&g[15..16], "8");
    }

    #[test]
    fn xml_lists_outputs() {
        let s = case1_scene(0.05, ElasticModel::Corrected, None);
        let xml = model_description_xml(&s);
        assert!(xml.contains("fmiVersion=\"2.0\""));
        assert!(xml.contains("name=\"s100.uz\""));
        assert!(xml.contains("<Outputs>"));
        assert!(!xml.contains("NaN"));
    }
}
