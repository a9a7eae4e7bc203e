//! Bad scenes give an error naming the field and the problem, never a panic.
use mps_solid::cases::{case1_scene, case2_scene, Support};
use mps_solid::physics::ElasticModel;
use mps_solid::{Scene, Simulation};

fn base() -> serde_json::Value {
    serde_json::from_str(
        &case2_scene(0.025, ElasticModel::Corrected, None, Support::Face).to_json(),
    )
    .unwrap()
}

fn error_of(v: serde_json::Value) -> String {
    let text = v.to_string();
    match Scene::from_json(&text) {
        Ok(s) => match Simulation::new(&s) {
            Ok(_) => panic!("scene accepted: {text}"),
            Err(e) => e.to_string(),
        },
        Err(e) => e.to_string(),
    }
}

#[test]
fn each_bad_field_is_named() {
    type Edit = Box<dyn Fn(&mut serde_json::Value)>;
    let cases: Vec<(&str, Edit, &str)> = vec![
        (
            "unknown field",
            Box::new(|v| v["colour"] = "red".into()),
            "unknown field `colour`",
        ),
        (
            "nested unknown field",
            Box::new(|v| v["bodies"][0]["material"]["yield"] = 1.0.into()),
            "unknown field `yield`",
        ),
        (
            "nu = 0.5",
            Box::new(|v| v["bodies"][0]["material"]["poisson"] = 0.5.into()),
            "material.poisson",
        ),
        (
            "E = 0",
            Box::new(|v| v["bodies"][0]["material"]["young"] = 0.0.into()),
            "material.young",
        ),
        (
            "E < 0",
            Box::new(|v| v["bodies"][0]["material"]["young"] = (-1.0).into()),
            "material.young",
        ),
        (
            "rho = 0",
            Box::new(|v| v["bodies"][0]["material"]["density"] = 0.0.into()),
            "material.density",
        ),
        (
            "dp = 0",
            Box::new(|v| v["particle_spacing"] = 0.0.into()),
            "particle_spacing",
        ),
        (
            "dp < 0",
            Box::new(|v| v["particle_spacing"] = (-0.1).into()),
            "particle_spacing",
        ),
        (
            "no bodies",
            Box::new(|v| v["bodies"] = serde_json::json!([])),
            "bodies",
        ),
        (
            "no boxes",
            Box::new(|v| v["bodies"][0]["boxes"] = serde_json::json!([])),
            "boxes",
        ),
        (
            "box not a multiple of dp",
            Box::new(|v| v["bodies"][0]["boxes"][0]["max"][0] = 1.01.into()),
            "boxes[0]",
        ),
        (
            "probe outside",
            Box::new(|v| v["probes"][0]["point"] = serde_json::json!([5.0, 0.0, 0.0])),
            "probes[0]",
        ),
        (
            "2 components in 3D",
            Box::new(|v| v["gravity"]["vector"] = serde_json::json!([0.0, -9.81])),
            "gravity.vector",
        ),
        (
            "dimension 4",
            Box::new(|v| v["dimension"] = 4.into()),
            "dimension",
        ),
        (
            "too many particles",
            Box::new(|v| v["solver"]["max_particles"] = 100.into()),
            "max_particles",
        ),
        (
            "negative end time",
            Box::new(|v| v["end_time"] = (-1.0).into()),
            "end_time",
        ),
        (
            "unknown body of a group",
            Box::new(|v| v["boundaries"][0]["body"] = "nope".into()),
            "boundaries[0]",
        ),
        (
            "empty region",
            Box::new(|v| v["boundaries"][0]["region"]["min"][0] = 5.0.into()),
            "boundaries[0]",
        ),
        (
            "bad axis",
            Box::new(|v| v["boundaries"][1]["axes"] = serde_json::json!(["w"])),
            "axes",
        ),
        (
            "bad model",
            Box::new(|v| v["solver"]["model"] = "magic".into()),
            "model",
        ),
        (
            "safety above 1",
            Box::new(|v| v["solver"]["safety"] = 2.0.into()),
            "solver.safety",
        ),
        (
            // Issue 7: above 0.8 soft bodies collapsing under load blew up.
            "safety 1",
            Box::new(|v| v["solver"]["safety"] = 1.0.into()),
            "solver.safety",
        ),
        (
            "bad name",
            Box::new(|v| v["name"] = "1 bad name".into()),
            "name",
        ),
        // Issue 8, item 1: absurd values that made a run never end are refused by range.
        // (serde_json parses 1e-30 as 9.999999999999999e-31, so the value itself is not
        // compared.)
        (
            "dt = 1e-30",
            Box::new(|v| v["solver"]["dt"] = 1e-30.into()),
            "solver.dt: must be in [1e-12, 1000] s, got ",
        ),
        (
            "density 1e-30",
            Box::new(|v| v["bodies"][0]["material"]["density"] = 1e-30.into()),
            "material.density: must be in [0.001, 100000] kg/m3, got ",
        ),
        (
            "young 1e30",
            Box::new(|v| v["bodies"][0]["material"]["young"] = 1e30.into()),
            "material.young: must be in [1, 1e13] Pa, got ",
        ),
        (
            "poisson just below 0.5",
            Box::new(|v| v["bodies"][0]["material"]["poisson"] = 0.49999999999999994.into()),
            "material.poisson: must be in [-0.999, 0.499], got 0.49999999999999994",
        ),
        (
            "safety 1e-300",
            Box::new(|v| v["solver"]["safety"] = 1e-300.into()),
            "solver.safety: must be in [0.01, 0.8], got ",
        ),
        (
            "output_interval 1e-9",
            Box::new(|v| v["output_interval"] = 1e-9.into()),
            "output_interval",
        ),
        (
            "end_time 1e30",
            Box::new(|v| v["end_time"] = 1e30.into()),
            "end_time: must be in [1e-9, 1e9] s, got ",
        ),
        (
            "damping 1e30",
            Box::new(|v| v["solver"]["damping"] = 1e30.into()),
            "solver.damping",
        ),
        (
            "fracture strain 1e-300",
            Box::new(|v| v["solver"]["fracture_strain"] = 1e-300.into()),
            "solver.fracture_strain",
        ),
        (
            "max_steps 0",
            Box::new(|v| v["solver"]["max_steps"] = 0.into()),
            "solver.max_steps",
        ),
        // Item 16: text that an FMU's modelDescription.xml cannot hold.
        (
            "NUL in a body name",
            Box::new(|v| v["bodies"][0]["name"] = "be\u{0}am".into()),
            "bodies[0].name: contains the control character U+0000",
        ),
        (
            "U+0001 in the description",
            Box::new(|v| v["description"] = "a\u{1}b".into()),
            "description: contains the control character U+0001",
        ),
        (
            "escape in a probe name",
            Box::new(|v| v["probes"][0]["name"] = "tip\u{1b}".into()),
            "probes[0].name",
        ),
        (
            "line feed in a boundary name",
            Box::new(|v| v["boundaries"][0]["name"] = "a\nb".into()),
            "boundaries[0].name",
        ),
    ];
    for (what, edit, needle) in cases {
        let mut v = base();
        edit(&mut v);
        let e = error_of(v);
        assert!(
            e.contains(needle),
            "{what}: error '{e}' does not mention '{needle}'"
        );
    }
}

#[test]
fn malformed_text_is_an_error_not_a_panic() {
    for text in ["", "{", "[]", "null", "{\"name\": 3}", "\u{0}"] {
        assert!(Scene::from_json(text).is_err());
    }
    assert!(Scene::from_toml("name = ").is_err());
    assert!(Scene::load(std::path::Path::new("/nonexistent/scene.json"))
        .unwrap_err()
        .to_string()
        .contains("cannot read"));
}

#[test]
fn a_fixed_dt_far_below_the_stable_step_is_refused_when_built() {
    let mut v = base();
    v["solver"]["dt"] = 1e-11.into();
    let e = error_of(v);
    assert!(
        e.contains("solver.dt") && e.contains("below 1e-6 x the stable step"),
        "{e}"
    );
}

#[test]
fn line_breaks_and_tabs_are_fine_in_the_description() {
    let mut v = base();
    v["description"] = "line one\n\tline two\r\n".into();
    Scene::from_json(&v.to_string()).unwrap();
}

#[test]
fn trailing_data_after_the_scene_is_refused() {
    let text = base().to_string();
    Scene::from_json(&format!("{text} \n\t")).expect("whitespace is fine");
    for bad in [
        format!("{text}xyz"),
        format!("{text}{text}"),
        format!("{text}\n}}"),
    ] {
        let e = Scene::from_json(&bad).unwrap_err().to_string();
        assert!(
            e.contains("trailing characters") && e.contains("only whitespace may follow"),
            "{e}"
        );
    }
}

#[test]
fn numbers_in_messages_are_short() {
    for (path, x) in [("density", 1e-300), ("young", 1e300), ("density", 5e-324)] {
        let mut v = base();
        v["bodies"][0]["material"][path] = x.into();
        let e = error_of(v);
        assert!(e.len() < 200, "{} characters: {e}", e.len());
        assert!(!e.contains("0000000000"), "{e}");
    }
    let mut v = base();
    v["particle_spacing"] = 1e-300.into();
    let e = error_of(v);
    assert!(e.len() < 300 && !e.contains("0000000000"), "{e}");
}

#[test]
fn toml_and_json_describe_the_same_scene() {
    let s = case1_scene(0.05, ElasticModel::Corrected, None);
    let t = toml::to_string(&s).unwrap();
    assert_eq!(Scene::from_toml(&t).unwrap(), s);
}

#[test]
fn load_region_names_are_unique_and_distinct_from_probe_names() {
    // Found while building the coupling example: a probe and a load region named 'tip' both
    // give the FMU outputs tip.ux/.vx, which silently became tip.ux and tip.ux_2.
    let mut v = base();
    let probe = v["probes"][0]["name"].as_str().unwrap().to_string();
    let body = v["bodies"][0]["name"].clone();
    let region = v["bodies"][0]["boxes"][0].clone();
    v["loads"] = serde_json::json!([{ "name": probe, "body": body, "region": region }]);
    let e = error_of(v.clone());
    assert!(
        e.contains(".name") && e.contains("a load region has the same name"),
        "{e}"
    );
    v["loads"] = serde_json::json!([
        { "name": "push", "body": body, "region": region },
        { "name": "push", "body": body, "region": region }
    ]);
    let e = error_of(v);
    assert!(
        e.contains("loads[1]") && e.contains("duplicate load region name"),
        "{e}"
    );
}
