//! The scene format's JSON Schema (src/scene/schema.rs): the committed copies
//! (schema/scene.schema.json, docs/scene-reference.md) are what the scene types generate today
//! (regenerate with `MPS_BLESS=1 cargo test --release --test suite scene_schema::`), every field
//! carries its description, unit, range (from scene::limits) and default, every scene file of
//! the repository validates against it and names it, wrong scenes fail it on the field that the
//! scene validation names too, and the `$schema` key changes nothing of a scene.
use mps_solid::fmi::model_description::guid;
use mps_solid::scene::limits;
use mps_solid::scene::schema::{
    fields, holds_numbers, reference_markdown, scene_schema, scene_schema_checked,
    scene_schema_text, unit_of, REFERENCE_FILE, SCHEMA_FILE, SCHEMA_KEY,
};
use mps_solid::Scene;
use serde_json::{json, Value};
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Compares a committed file with its generated text (writes it under MPS_BLESS).
fn check_fresh(rel: &str, fresh: &str) {
    let path = root().join(rel);
    if std::env::var_os("MPS_BLESS").is_some() {
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(&path, fresh).unwrap();
    }
    let committed = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        committed == fresh,
        "{rel} is stale: regenerate it with `MPS_BLESS=1 cargo test --release --test suite scene_schema::` \
         (or `mps schema{}`)",
        if rel.ends_with(".md") { " --markdown" } else { "" }
    );
}

#[test]
fn committed_schema_is_fresh() {
    check_fresh(SCHEMA_FILE, &scene_schema_text());
}

#[test]
fn committed_reference_page_is_fresh() {
    check_fresh(REFERENCE_FILE, &reference_markdown());
}

#[test]
fn every_limit_lands_on_its_field() {
    let (schema, missing) = scene_schema_checked();
    assert!(
        missing.is_empty(),
        "limits naming no field of the schema: {missing:?}"
    );
    let def = |t: &str, f: &str| schema["definitions"][t]["properties"][f].clone();
    let d = def("Material", "density");
    assert_eq!(d["minimum"], json!(limits::DENSITY.min));
    assert_eq!(d["maximum"], json!(limits::DENSITY.max));
    let re = def("SolverOptions", "re_factor");
    assert_eq!(re["exclusiveMinimum"], json!(1.0));
    assert_eq!(re["maximum"], json!(4.0));
    assert!(re.get("minimum").is_none());
    let o = def("ContactOptions", "overlap_fraction");
    assert_eq!(
        (o["exclusiveMinimum"].clone(), o["exclusiveMaximum"].clone()),
        (json!(0.0), json!(1.0))
    );
    assert_eq!(def("SolverOptions", "max_steps")["minimum"], json!(1));
    assert_eq!(
        schema["properties"]["end_time"]["maximum"],
        json!(limits::END_TIME.max)
    );
    assert_eq!(
        def("ModeShapeProfile", "length")["exclusiveMinimum"],
        json!(0.0)
    );
}

#[test]
fn every_field_is_described_and_every_number_has_a_unit() {
    let schema = scene_schema();
    let all = fields(&schema);
    assert!(all.len() > 60, "only {} fields found", all.len());
    let mut problems = Vec::new();
    for f in &all {
        let s = schema.pointer(&f.pointer).unwrap();
        let d = mps_solid::scene::schema::description(&schema, s);
        if d.trim().is_empty() {
            problems.push(format!("{}: no description (a doc comment)", f.path));
        }
        // Numbers carry a unit in the doc comment, "(-)" when dimensionless; the angular
        // velocity's alternatives (a number or an array) are described on the field itself.
        if holds_numbers(&schema, s) && unit_of(&d).is_none() {
            problems.push(format!(
                "{}: a number without a unit in its description: {d:?}",
                f.path
            ));
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

/// The smallest scene: only the required fields.
const MINIMAL: &str = r#"{
  "name": "minimal", "dimension": 2, "particle_spacing": 0.01,
  "bodies": [{ "name": "b", "material": { "density": 1000.0, "young": 1e6, "poisson": 0.3 },
               "boxes": [{ "min": [0.0, 0.0], "max": [0.1, 0.02] }] }],
  "end_time": 0.01, "output_interval": 0.001
}"#;

#[test]
fn defaults_are_the_serde_defaults() {
    // Every default the schema states is what a scene that leaves the field out gets.
    let schema = scene_schema();
    let scene = Scene::from_json(MINIMAL).unwrap();
    let value: Value = serde_json::from_str(&scene.to_json()).unwrap();
    let mut checked = 0;
    for f in fields(&schema) {
        let s = schema.pointer(&f.pointer).unwrap();
        let (Some(default), false) = (s.get("default"), f.path.contains("[]")) else {
            continue;
        };
        let pointer = format!("/{}", f.path.replace('.', "/"));
        let actual = value
            .pointer(&pointer)
            .unwrap_or_else(|| panic!("{} not in the scene", f.path));
        assert_eq!(actual, default, "{}: the schema's default", f.path);
        checked += 1;
    }
    assert!(checked >= 15, "only {checked} defaults checked");
    assert_eq!(
        schema["definitions"]["SolverOptions"]["properties"]["re_factor"]["default"],
        json!(2.1)
    );
}

fn validator() -> jsonschema::Validator {
    let text = std::fs::read_to_string(root().join(SCHEMA_FILE)).expect("the committed schema");
    let schema: Value = serde_json::from_str(&text).unwrap();
    jsonschema::draft7::new(&schema).expect("the schema is a valid draft-07 schema")
}

/// The scene files of the repository: scenes/, tests/data/, docs/**/scenes/, fuzz/scenes/.
fn scene_files() -> Vec<PathBuf> {
    let mut v = Vec::new();
    let mut add = |dir: &Path| {
        if let Ok(d) = std::fs::read_dir(dir) {
            for e in d.flatten() {
                let p = e.path();
                if p.extension().is_some_and(|x| x == "json") {
                    v.push(p);
                }
            }
        }
    };
    for d in [
        "scenes",
        "tests/data",
        "fuzz/scenes",
        "docs/case3-study/scenes",
    ] {
        add(&root().join(d));
    }
    v.sort();
    v
}

#[test]
fn every_scene_file_validates_and_names_the_schema() {
    let v = validator();
    let files = scene_files();
    assert!(files.len() >= 10, "only {} scene files", files.len());
    for p in files {
        let text = std::fs::read_to_string(&p).unwrap();
        let value: Value = serde_json::from_str(&text).unwrap();
        let errors: Vec<String> = v
            .iter_errors(&value)
            .map(|e| format!("{} at {}", e, e.instance_path()))
            .collect();
        assert!(errors.is_empty(), "{}: {}", p.display(), errors.join("; "));
        // The file names the committed schema by its path relative to the file.
        let reference = value[SCHEMA_KEY]
            .as_str()
            .unwrap_or_else(|| panic!("{} has no \"$schema\"", p.display()));
        let target = p.parent().unwrap().join(reference);
        assert_eq!(
            target.canonicalize().ok(),
            root().join(SCHEMA_FILE).canonicalize().ok(),
            "{}: \"$schema\" should lead to {SCHEMA_FILE}",
            p.display()
        );
        Scene::load(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    }
}

fn small2d() -> Value {
    serde_json::from_str(&std::fs::read_to_string(root().join("tests/data/small2d.json")).unwrap())
        .unwrap()
}

#[test]
fn wrong_scenes_fail_on_the_field_the_validation_names() {
    let v = validator();
    // (what is wrong, JSON pointer of the value, instance path the schema reports, a text
    // the scene validation's field must contain)
    type Case = (
        &'static str,
        &'static str,
        Value,
        &'static str,
        &'static str,
    );
    let cases: Vec<Case> = vec![
        (
            "density below the range",
            "/bodies/0/material/density",
            json!(-1.0),
            "/bodies/0/material/density",
            "material.density",
        ),
        (
            "poisson at 0.5",
            "/bodies/0/material/poisson",
            json!(0.5),
            "/bodies/0/material/poisson",
            "material.poisson",
        ),
        (
            "re_factor at its open end",
            "/solver/re_factor",
            json!(1.0),
            "/solver/re_factor",
            "solver.re_factor",
        ),
        (
            "overlap of a whole spacing",
            "/solver/contact/overlap_fraction",
            json!(1.0),
            "/solver/contact/overlap_fraction",
            "solver.contact.overlap_fraction",
        ),
        (
            "an unknown operator",
            "/solver/model",
            json!("fem"),
            "/solver/model",
            "solver.model",
        ),
        (
            "dimension 4",
            "/dimension",
            json!(4),
            "/dimension",
            "dimension",
        ),
        (
            "zero spacing",
            "/particle_spacing",
            json!(0.0),
            "/particle_spacing",
            "particle_spacing",
        ),
        (
            "safety above 0.8",
            "/solver/safety",
            json!(0.9),
            "/solver/safety",
            "solver.safety",
        ),
        (
            "no steps",
            "/solver/max_steps",
            json!(0),
            "/solver/max_steps",
            "solver.max_steps",
        ),
        (
            "a velocity that is text",
            "/bodies/0/velocity",
            json!("fast"),
            "/bodies/0/velocity",
            "velocity",
        ),
        (
            "a boundary kind not known",
            "/boundaries/0/kind",
            json!("glued"),
            "/boundaries/0/kind",
            "kind",
        ),
        (
            "end time of zero",
            "/end_time",
            json!(0.0),
            "/end_time",
            "end_time",
        ),
    ];
    for (what, pointer, value, instance, field) in cases {
        let mut scene = small2d();
        // Create the parent objects the pointer needs (solver, contact).
        let (parent, key) = pointer.rsplit_once('/').unwrap();
        let mut at = &mut scene;
        for seg in parent.split('/').skip(1) {
            at = if let Ok(i) = seg.parse::<usize>() {
                &mut at[i]
            } else {
                at.as_object_mut().unwrap().entry(seg).or_insert(json!({}))
            };
        }
        at[key] = value;
        let errors: Vec<String> = v
            .iter_errors(&scene)
            .map(|e| e.instance_path().to_string())
            .collect();
        assert!(
            errors.iter().any(|p| p == instance),
            "{what}: the schema reports {errors:?}, expected {instance}"
        );
        let e = Scene::from_json(&scene.to_string()).expect_err(what);
        assert!(
            e.field.contains(field),
            "{what}: the scene validation names {:?} ({}), expected {field}",
            e.field,
            e.message
        );
    }
    // A misspelt field: the schema names its owner (additionalProperties), serde the field.
    let mut scene = small2d();
    scene["bodies"][0]["material"]["densty"] = json!(1000.0);
    let errors: Vec<String> = v
        .iter_errors(&scene)
        .map(|e| e.instance_path().to_string())
        .collect();
    assert!(
        errors.iter().any(|p| p == "/bodies/0/material"),
        "{errors:?}"
    );
    let e = Scene::from_json(&scene.to_string()).unwrap_err();
    assert!(e.message.contains("densty"), "{e}");
    // A missing required field.
    let mut scene = small2d();
    scene.as_object_mut().unwrap().remove("end_time");
    assert!(!v.is_valid(&scene));
    assert!(Scene::from_json(&scene.to_string()).is_err());
}

#[test]
fn the_schema_key_changes_nothing() {
    let plain = Scene::from_json(MINIMAL).unwrap();
    let named = MINIMAL.replacen('{', "{ \"$schema\": \"../schema/scene.schema.json\",", 1);
    let with = Scene::from_json(&named).unwrap();
    assert_eq!(with, plain);
    assert_eq!(with.to_json(), plain.to_json());
    assert_eq!(guid(&with), guid(&plain));
    assert!(!with.to_json().contains(SCHEMA_KEY));
    // Written with the key first, read back as the same scene.
    let text = plain.to_json_with_schema("../schema/scene.schema.json");
    assert!(
        text.starts_with("{\n  \"$schema\": \"../schema/scene.schema.json\",\n  \"name\""),
        "{text}"
    );
    assert_eq!(Scene::from_json(&text).unwrap(), plain);
    // Only at the top level: elsewhere it is an unknown field, named as before.
    let nested = MINIMAL.replacen("\"material\": {", "\"material\": { \"$schema\": \"x\",", 1);
    let e = Scene::from_json(&nested).unwrap_err();
    assert!(
        e.field.contains("material") && e.message.contains("$schema"),
        "{e}"
    );
    // TOML too.
    let toml = "\"$schema\" = \"../schema/scene.schema.json\"\nname = \"t\"\ndimension = 2\n\
                particle_spacing = 0.01\nend_time = 0.01\noutput_interval = 0.001\n\
                [[bodies]]\nname = \"b\"\nmaterial = { density = 1000.0, young = 1e6, poisson = 0.3 }\n\
                boxes = [{ min = [0.0, 0.0], max = [0.1, 0.02] }]\n";
    Scene::from_toml(toml).unwrap();
    // Errors after the key keep their position and field.
    let bad = named.replacen("\"dimension\": 2", "\"dimension\": \"two\"", 1);
    let e = Scene::from_json(&bad).unwrap_err();
    assert_eq!(e.field, "dimension");
    assert!(e.message.contains("line"), "{e}");
}
