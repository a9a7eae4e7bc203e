//! modelDescription.xml: modelDescription/<scene>.xml is the generated XML of every scene in
//! scenes/ (regenerate with `cargo run --release -- pack --xml-only --write-xml
//! modelDescription scenes/*.json`), its structure follows the variable table, and pack_fmu
//! writes a complete FMU.
use crate::common;

use mps_solid::fmi::model_description::guid;
use mps_solid::fmi::pack::{documentation_html, model_description_xml, pack_fmu};
use mps_solid::fmi::variables::{Causality, VariableTable};
use mps_solid::Scene;
use quick_xml::events::Event;
use quick_xml::Reader;
use std::collections::HashMap;
use std::io::Read;
use std::path::PathBuf;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn scenes() -> Vec<(PathBuf, Scene)> {
    let mut v: Vec<_> = std::fs::read_dir(root().join("scenes"))
        .map(|d| d.filter_map(|e| e.ok()).map(|e| e.path()).collect())
        .unwrap_or_default();
    v.retain(|p: &PathBuf| p.extension().is_some_and(|e| e == "json"));
    v.sort();
    v.into_iter()
        .map(|p| (p.clone(), Scene::load(&p).unwrap()))
        .collect()
}

#[test]
fn committed_model_descriptions_are_fresh() {
    let all = scenes();
    assert!(!all.is_empty(), "no scenes/*.json");
    for (path, scene) in all {
        let file = root()
            .join("modelDescription")
            .join(format!("{}.xml", scene.name));
        let committed = std::fs::read_to_string(&file).unwrap_or_default();
        assert!(
            committed == model_description_xml(&scene),
            "{} is stale for {}: run `cargo run --release -- pack --xml-only --write-xml modelDescription scenes/*.json`",
            file.display(),
            path.display()
        );
    }
}

/// Elements with their attributes, in document order.
fn elements(xml: &str) -> Vec<(String, HashMap<String, String>)> {
    let mut r = Reader::from_str(xml);
    let mut out = Vec::new();
    loop {
        match r.read_event().expect("well-formed XML") {
            Event::Start(e) | Event::Empty(e) => {
                let name = String::from_utf8(e.name().as_ref().to_vec()).unwrap();
                let attrs = e
                    .attributes()
                    .map(|a| {
                        let a = a.unwrap();
                        (
                            String::from_utf8(a.key.as_ref().to_vec()).unwrap(),
                            a.unescape_value().unwrap().into_owned(),
                        )
                    })
                    .collect();
                out.push((name, attrs));
            }
            Event::Eof => break,
            _ => {}
        }
    }
    out
}

#[test]
fn xml_follows_the_variable_table() {
    let mut all: Vec<Scene> = scenes().into_iter().map(|(_, s)| s).collect();
    for f in ["small2d.json", "small3d.json"] {
        all.push(Scene::load(&root().join("tests/data").join(f)).unwrap());
    }
    for scene in all {
        let xml = model_description_xml(&scene);
        let table = VariableTable::new(&scene);
        let els = elements(&xml);
        let root_attrs = &els[0].1;
        assert_eq!(els[0].0, "fmiModelDescription");
        assert_eq!(root_attrs["fmiVersion"], "2.0");
        assert_eq!(root_attrs["guid"], guid(&scene));
        assert_eq!(root_attrs["variableNamingConvention"], "structured");
        let cs = &els.iter().find(|e| e.0 == "CoSimulation").unwrap().1;
        assert_eq!(cs["modelIdentifier"], scene.name);
        for flag in [
            "canHandleVariableCommunicationStepSize",
            "canGetAndSetFMUstate",
            "canSerializeFMUstate",
            "canInterpolateInputs",
        ] {
            assert_eq!(cs[flag], "true", "{flag}");
        }
        let de = &els.iter().find(|e| e.0 == "DefaultExperiment").unwrap().1;
        assert_eq!(de["stopTime"].parse::<f64>().unwrap(), scene.end_time);
        assert_eq!(
            de["stepSize"].parse::<f64>().unwrap(),
            scene.output_interval
        );
        let units: Vec<&str> = els
            .iter()
            .filter(|e| e.0 == "Unit")
            .map(|e| e.1["name"].as_str())
            .collect();
        // Every variable in table order, with the attributes the standard requires.
        let vars: Vec<usize> = (0..els.len())
            .filter(|&i| els[i].0 == "ScalarVariable")
            .collect();
        assert_eq!(vars.len(), table.vars.len());
        for (v, &i) in table.vars.iter().zip(&vars) {
            let (sv, ty) = (&els[i].1, &els[i + 1]);
            assert_eq!(sv["name"], v.name);
            assert_eq!(sv["valueReference"], v.value_reference.to_string());
            assert_eq!(sv["causality"], v.causality.name());
            assert_eq!(ty.0, v.ty.name());
            match v.causality {
                Causality::Output => {
                    assert_eq!(sv["initial"], "calculated");
                    assert!(
                        !ty.1.contains_key("start"),
                        "{}: outputs have no start",
                        v.name
                    );
                }
                _ => {
                    assert!(!sv.contains_key("initial"), "{}", v.name);
                    assert_eq!(ty.1["start"].parse::<f64>().unwrap(), v.start.unwrap());
                }
            }
            if let Some(u) = ty.1.get("unit") {
                assert!(units.contains(&u.as_str()), "unit {u} undefined");
            }
        }
        // ModelStructure: 1-based indices of every output, in Outputs and InitialUnknowns.
        let expected: Vec<String> = table
            .output_indices()
            .iter()
            .map(|i| i.to_string())
            .collect();
        let start = els.iter().position(|e| e.0 == "Outputs").unwrap();
        let init = els.iter().position(|e| e.0 == "InitialUnknowns").unwrap();
        let idx = |range: std::ops::Range<usize>| -> Vec<String> {
            els[range]
                .iter()
                .filter(|e| e.0 == "Unknown")
                .map(|e| e.1["index"].clone())
                .collect()
        };
        assert_eq!(idx(start..init), expected);
        assert_eq!(idx(init..els.len()), expected);
        for e in &els[init..] {
            if e.0 == "Unknown" {
                let deps = &e.1["dependencies"];
                for d in deps.split_whitespace() {
                    let k: usize = d.parse().unwrap();
                    assert_eq!(table.vars[k - 1].causality, Causality::Parameter);
                }
            }
        }
    }
}

#[test]
#[ignore = "slow (10 s on a loaded 2-core machine): the full test command runs it"]
fn pack_writes_a_complete_fmu() {
    let scene = Scene::load(&root().join("tests/data/small3d.json")).unwrap();
    let dir = std::env::temp_dir().join(format!("mps-pack-{}", std::process::id()));
    let out = dir.join("sub/small3d.fmu");
    pack_fmu(&scene, &common::built_library(), &out).unwrap();
    let mut z = zip::ZipArchive::new(std::fs::File::open(&out).unwrap()).unwrap();
    let mut read = |name: &str| {
        let mut s = Vec::new();
        z.by_name(name)
            .unwrap_or_else(|e| panic!("{name}: {e}"))
            .read_to_end(&mut s)
            .unwrap();
        s
    };
    // The packed XML is the canonical one with the packing date.
    let packed = String::from_utf8(read("modelDescription.xml")).unwrap();
    let date = packed
        .split(" generationDateAndTime=\"")
        .nth(1)
        .and_then(|r| r.split('"').next())
        .expect("generationDateAndTime in the packed modelDescription.xml");
    assert!(date.len() == 20 && date.ends_with('Z'), "{date}");
    assert_eq!(
        packed.replace(&format!(" generationDateAndTime=\"{date}\""), ""),
        model_description_xml(&scene)
    );
    // The packed scene is the scene itself; only the folder its meshes are read from (not
    // part of the file: the FMU reads them from its resources) differs.
    let loaded_from_its_folder = Scene {
        base_dir: None,
        ..scene.clone()
    };
    assert_eq!(
        Scene::from_json(&String::from_utf8(read("resources/scene.json")).unwrap()).unwrap(),
        loaded_from_its_folder
    );
    assert_eq!(&read("binaries/linux64/small3d.so")[..4], b"\x7fELF");
    let doc = String::from_utf8(read("documentation/index.html")).unwrap();
    let sim = mps_solid::sim::Simulation::new(&scene).unwrap();
    assert_eq!(doc, documentation_html(&scene, &sim));
    // Issue 9: every load region, boundary group and probe is listed with its particle count.
    for (r, l) in scene.loads.iter().enumerate() {
        let row = format!("<code>{}</code>", l.name);
        assert!(doc.contains(&row), "load region {} undocumented", l.name);
        assert!(sim.load_size(r) > 0);
        assert!(doc.contains(&format!("</td><td>{}</td></tr>", sim.load_size(r))));
    }
    for (g, b) in scene.boundaries.iter().enumerate() {
        assert!(doc.contains(&format!("<code>{}</code>", b.name)));
        assert!(doc.contains(&format!("</td><td>{}</td></tr>", sim.group_size(g))));
    }
    for p in &scene.probes {
        assert!(doc.contains(&format!("<code>{}</code>", p.name)));
    }
    for v in VariableTable::new(&scene).vars {
        assert!(
            doc.contains(&format!("<code>{}</code>", v.name)),
            "{} undocumented",
            v.name
        );
    }
    // Errors name the problem.
    let bad = pack_fmu(&scene, &root().join("Cargo.toml"), &dir.join("x.fmu")).unwrap_err();
    assert!(bad.contains("not an ELF shared library"), "{bad}");
    let missing = pack_fmu(&scene, &dir.join("nothing.so"), &dir.join("x.fmu")).unwrap_err();
    assert!(missing.contains("cannot read the library"), "{missing}");
    std::fs::remove_dir_all(&dir).ok();
}

/// The decimal numbers of a text (as written: digits, one point, an optional exponent).
fn numbers(text: &str) -> Vec<&str> {
    let b = text.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        if b[i].is_ascii_digit()
            && (i == 0 || !(b[i - 1].is_ascii_alphanumeric() || b[i - 1] == b'_'))
        {
            let s = i;
            while i < b.len() && (b[i].is_ascii_digit() || b[i] == b'.') {
                i += 1;
            }
            if i + 1 < b.len() && b[i] == b'e' && (b[i + 1].is_ascii_digit() || b[i + 1] == b'-') {
                i += 2;
                while i < b.len() && b[i].is_ascii_digit() {
                    i += 1;
                }
            }
            out.push(text[s..i].trim_end_matches('.'));
        } else {
            i += 1;
        }
    }
    out
}

/// Significant digits of a decimal number as written.
fn significant_digits(n: &str) -> usize {
    let mantissa = n.split('e').next().unwrap();
    let digits: String = mantissa.chars().filter(|c| c.is_ascii_digit()).collect();
    digits.trim_start_matches('0').len()
}

/// "[a, b]" ranges quoted in a text, as numbers.
fn quoted_ranges(text: &str) -> Vec<(f64, f64)> {
    let mut out = Vec::new();
    for part in text.split('[').skip(1) {
        let Some(inner) = part.split(']').next() else {
            continue;
        };
        let v: Vec<&str> = inner.split(", ").collect();
        if let [a, b] = v[..] {
            if let (Ok(a), Ok(b)) = (a.parse::<f64>(), b.parse::<f64>()) {
                out.push((a, b));
            }
        }
    }
    out
}

#[test]
fn generated_texts_agree_with_the_tables() {
    // Issue 27.13: the FMU's documentation contradicted itself. Every text is generated from the
    // variable table and the limits table; these checks hold for every scene in scenes/.
    for (path, scene) in scenes() {
        let table = VariableTable::new(&scene);
        let at = path.display();
        let sim = mps_solid::Simulation::new(&scene).unwrap();
        let doc = documentation_html(&scene, &sim);
        let xml = model_description_xml(&scene);
        for v in &table.vars {
            // A range a description quotes is the variable's declared min/max.
            for (lo, hi) in quoted_ranges(&v.description) {
                assert_eq!(
                    (Some(lo), Some(hi)),
                    (v.min, v.max),
                    "{at}: {} quotes [{lo}, {hi}] but declares min {:?} max {:?}: {}",
                    v.name,
                    v.min,
                    v.max,
                    v.description
                );
            }
            // No description carries round-off digits (0.48750000000000004): 12 significant
            // digits resolve a position to 1e-12 of its size, far below the 2^-20 of the
            // particle spacing that positions keep (physics::world::build::MIN_SPACING_BITS).
            for n in numbers(&v.description) {
                assert!(
                    significant_digits(n) <= 12,
                    "{at}: {}: '{n}' in '{}'",
                    v.name,
                    v.description
                );
            }
            // The gravity inputs describe the rule in force: gravity_source.
            if v.name.starts_with("gravity_") && v.causality == Causality::Input {
                assert!(
                    v.description.contains("gravity_source")
                        && !v.description.contains("Until the host sets"),
                    "{at}: {}: {}",
                    v.name,
                    v.description
                );
            }
        }
        // Integer start values and bounds are integers in the XML and on the page.
        for (name, attrs) in elements(&xml) {
            if name == "Integer" {
                for k in ["start", "min", "max"] {
                    if let Some(s) = attrs.get(k) {
                        assert!(s.parse::<i64>().is_ok(), "{at}: Integer {k} = '{s}'");
                    }
                }
            }
        }
        for v in table.vars.iter().filter(|v| v.ty.name() == "Integer") {
            if let Some(s) = v.start {
                let cell = format!(
                    "<td>Integer</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td>",
                    v.causality.name(),
                    v.variability.name(),
                    v.unit.unwrap_or("-"),
                    s as i64
                );
                assert!(
                    doc.contains(&cell),
                    "{at}: {} start on the page is not {}",
                    v.name,
                    s as i64
                );
            }
        }
        // The page's numbers: no round-off digits, no "1 bodies".
        let escaped = scene
            .description
            .replace('&', "&amp;")
            .replace('<', "&lt;")
            .replace('>', "&gt;")
            .replace('"', "&quot;");
        for n in numbers(&doc.replace(&escaped, "")) {
            assert!(significant_digits(n) <= 12, "{at}: '{n}' on the page");
        }
        assert!(!doc.contains(" 1 bodies"), "{at}: '1 bodies'");
        // The range column of the page is the declared min/max.
        for v in &table.vars {
            if let (Some(lo), Some(hi)) = (v.min, v.max) {
                let row_start = format!("<td><code>{}</code></td>", v.name);
                let row = doc
                    .lines()
                    .find(|l| l.contains(&row_start))
                    .unwrap_or_else(|| panic!("{at}: no row of {}", v.name));
                let ranges = quoted_ranges(row);
                assert_eq!(ranges.first(), Some(&(lo, hi)), "{at}: {row}");
                assert!(ranges.iter().all(|r| *r == (lo, hi)), "{at}: {row}");
            }
        }
    }
}
