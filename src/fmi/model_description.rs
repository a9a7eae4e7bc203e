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

/// Who made the FMU's code (`author` of the modelDescription): Cargo.toml's `authors`.
fn author() -> String {
    env!("CARGO_PKG_AUTHORS").replace(':', ", ")
}

/// A time in seconds since 1970-01-01 UTC as an xs:dateTime in UTC, `YYYY-MM-DDThh:mm:ssZ`.
pub fn utc_date_time(secs: i64) -> String {
    let (days, s) = (secs.div_euclid(86_400), secs.rem_euclid(86_400));
    // Days to a proleptic Gregorian date (H. Hinnant's civil_from_days).
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!(
        "{year:04}-{month:02}-{day:02}T{:02}:{:02}:{:02}Z",
        s / 3600,
        s / 60 % 60,
        s % 60
    )
}

/// `generationDateAndTime` of a packed FMU: `source_date_epoch` (the value of the
/// `SOURCE_DATE_EPOCH` environment variable, seconds since 1970, for reproducible packages)
/// when given, else the current time.
pub fn generation_date_and_time(source_date_epoch: Option<&str>) -> Result<String, String> {
    let secs = match source_date_epoch {
        Some(v) => v.trim().parse::<i64>().map_err(|_| {
            format!("SOURCE_DATE_EPOCH = '{v}' is not a number of seconds since 1970-01-01")
        })?,
        None => std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_err(|e| format!("the system clock is before 1970: {e}"))?
            .as_secs() as i64,
    };
    Ok(utc_date_time(secs))
}

/// The modelDescription.xml of a scene's FMU in its canonical form: everything but
/// `generationDateAndTime`, so that it depends only on the scene and the crate version. This is
/// what modelDescription/<scene>.xml holds and is checked against.
pub fn model_description_xml(scene: &Scene) -> String {
    model_description_xml_dated(scene, None)
}

/// The modelDescription.xml written into a packed FMU: the canonical XML with
/// `generationDateAndTime` (from `SOURCE_DATE_EPOCH` when set, else now).
pub fn packed_model_description_xml(scene: &Scene) -> Result<String, String> {
    let epoch = std::env::var("SOURCE_DATE_EPOCH").ok();
    let date = generation_date_and_time(epoch.as_deref())?;
    Ok(model_description_xml_dated(scene, Some(&date)))
}

/// The modelDescription.xml of a scene's FMU, with `generationDateAndTime` if `date` is given.
fn model_description_xml_dated(scene: &Scene, date: Option<&str>) -> String {
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
    let author = author();
    // `version` is that of the model's code (the crate): the scene has no version of its own.
    let mut root: Vec<(&str, &str)> = vec![
        ("fmiVersion", "2.0"),
        ("modelName", &scene.name),
        ("guid", &guid),
        ("description", &description),
        ("author", &author),
        ("version", env!("CARGO_PKG_VERSION")),
        ("license", env!("CARGO_PKG_LICENSE")),
        ("generationTool", &tool),
    ];
    if let Some(d) = date {
        root.push(("generationDateAndTime", d));
    }
    root.push(("variableNamingConvention", "structured"));
    root.push(("numberOfEventIndicators", "0"));
    x.start("fmiModelDescription", &root, false);
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
        let int = |x: f64| (x as i64).to_string();
        let (min, max) = match v.ty {
            VarType::Integer => (v.min.map(int), v.max.map(int)),
            _ => (v.min.map(real), v.max.map(real)),
        };
        if v.causality == Causality::Parameter {
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
                .is_some_and(|vel| !vel.is_zero())
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

// The scene builders of the paper's cases are study code (feature `studies`).
#[cfg(all(test, feature = "studies"))]
mod tests {
    use super::*;
    use crate::physics::ElasticModel;
    use crate::studies::cases::case1_scene;

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
    fn root_element_carries_the_metadata() {
        let s = case1_scene(0.05, ElasticModel::Corrected, None);
        let xml = model_description_xml(&s);
        let version = format!("version=\"{}\"", env!("CARGO_PKG_VERSION"));
        for attr in [
            "author=\"mps-solid developers\"",
            version.as_str(),
            "license=\"MIT OR Apache-2.0\"",
            "generationTool=\"mps-solid ",
        ] {
            assert!(xml.contains(attr), "{attr} missing");
        }
        assert!(
            !xml.contains("generationDateAndTime"),
            "the canonical XML has no date"
        );
        let dated = model_description_xml_dated(&s, Some("2001-09-09T01:46:40Z"));
        assert!(dated.contains(" generationDateAndTime=\"2001-09-09T01:46:40Z\" "));
        assert_eq!(
            dated.replace(" generationDateAndTime=\"2001-09-09T01:46:40Z\"", ""),
            xml,
            "the date is the only difference"
        );
    }

    #[test]
    fn dates_are_utc_date_times() {
        assert_eq!(utc_date_time(0), "1970-01-01T00:00:00Z");
        assert_eq!(utc_date_time(951_782_400), "2000-02-29T00:00:00Z");
        assert_eq!(utc_date_time(1_000_000_000), "2001-09-09T01:46:40Z");
        assert_eq!(utc_date_time(4_102_444_799), "2099-12-31T23:59:59Z");
        assert_eq!(utc_date_time(-1), "1969-12-31T23:59:59Z");
        assert_eq!(
            generation_date_and_time(Some("1000000000")).unwrap(),
            "2001-09-09T01:46:40Z"
        );
        let e = generation_date_and_time(Some("yesterday")).unwrap_err();
        assert!(
            e.contains("SOURCE_DATE_EPOCH") && e.contains("yesterday"),
            "{e}"
        );
        let now = generation_date_and_time(None).unwrap();
        assert!(
            now.len() == 20 && now.ends_with('Z') && now.as_str() > "2024",
            "{now}"
        );
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
