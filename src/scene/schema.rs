//! The JSON Schema of the scene format (draft-07, which editors such as VS Code read), derived
//! from the serde types with schemars: each field's description is its doc comment (with its
//! unit), its default the serde default, and its range the entry of `scene::limits` for it
//! (`RANGES` and `BOUNDS`, found by field path, so a range is never typed twice). The scene
//! reference page (docs/scene-reference.md) is made from the same schema. `mps schema` prints
//! the one, `mps schema --markdown` the other; tests/suite/scene_schema.rs keeps the committed
//! copies fresh.
use super::limits::{self, num, Bound, Range};
use super::Scene;
use serde::de;
use serde_json::{json, Map, Value};

/// The top-level key a scene file may carry for editors: the address of the schema. The scene
/// ignores it (it is neither stored nor serialised, so it changes no GUID and no FMU state).
pub const SCHEMA_KEY: &str = "$schema";

/// Where the schema is committed, relative to the repository's root.
pub const SCHEMA_FILE: &str = "schema/scene.schema.json";

/// Where the scene reference page is committed, relative to the repository's root.
pub const REFERENCE_FILE: &str = "docs/scene-reference.md";

/// The schema of a scene file as JSON.
pub fn scene_schema() -> Value {
    scene_schema_checked().0
}

/// The schema, and the fields of `limits::RANGES` and `limits::BOUNDS` that name no field of
/// the schema (empty unless a field was renamed without its limit).
pub fn scene_schema_checked() -> (Value, Vec<&'static str>) {
    let generator = schemars::generate::SchemaSettings::draft07().into_generator();
    let mut schema = generator.into_root_schema_for::<Scene>().to_value();
    schema["title"] = json!("mps-solid scene");
    let root = schema
        .as_object_mut()
        .expect("the root schema is an object");
    root.get_mut("properties")
        .and_then(Value::as_object_mut)
        .expect("the scene has properties")
        .insert(
            SCHEMA_KEY.to_string(),
            json!({
                "description": "The address of this schema, for editors (VS Code completes and \
                                checks a scene that names it); mps ignores it.",
                "type": "string"
            }),
        );
    let fields = fields(&schema);
    let mut missing = Vec::new();
    for r in limits::RANGES {
        if !apply(&mut schema, &fields, r.field, |s| set_range(s, r)) {
            missing.push(r.field);
        }
    }
    for b in limits::BOUNDS {
        if !apply(&mut schema, &fields, b.field, |s| set_bound(s, b)) {
            missing.push(b.field);
        }
    }
    (schema, missing)
}

/// The schema as the committed file holds it: pretty JSON and a final line break.
pub fn scene_schema_text() -> String {
    serde_json::to_string_pretty(&scene_schema()).expect("a JSON value serialises") + "\n"
}

/// A field of the schema reached from the root: its path and where its schema lives.
#[derive(Clone, Debug)]
pub struct Field {
    /// Path from the scene's root; `[]` marks the elements of an array
    /// (`bodies[].material.density`).
    pub path: String,
    /// JSON pointer of the field's schema in the whole schema.
    pub pointer: String,
    /// Whether the owner requires the field.
    pub required: bool,
}

/// Every field of the schema, depth first in the schema's order, each path once.
pub fn fields(schema: &Value) -> Vec<Field> {
    let mut out = Vec::new();
    walk(schema, schema, "", "", &mut out, 0);
    let mut seen = std::collections::HashSet::new();
    out.retain(|f| seen.insert(f.path.clone()));
    out
}

fn walk(root: &Value, node: &Value, pointer: &str, path: &str, out: &mut Vec<Field>, depth: u32) {
    assert!(depth < 64, "the scene schema nests too deep at {path}");
    if let Some(r) = node.get("$ref").and_then(Value::as_str) {
        let target = r.trim_start_matches('#');
        if let Some(def) = root.pointer(target) {
            walk(root, def, target, path, out, depth + 1);
        }
    }
    for key in ["allOf", "anyOf", "oneOf"] {
        if let Some(list) = node.get(key).and_then(Value::as_array) {
            for (k, sub) in list.iter().enumerate() {
                walk(
                    root,
                    sub,
                    &format!("{pointer}/{key}/{k}"),
                    path,
                    out,
                    depth + 1,
                );
            }
        }
    }
    if let Some(items) = node.get("items") {
        walk(
            root,
            items,
            &format!("{pointer}/items"),
            &format!("{path}[]"),
            out,
            depth + 1,
        );
    }
    if let Some(props) = node.get("properties").and_then(Value::as_object) {
        let required: Vec<&str> = node
            .get("required")
            .and_then(Value::as_array)
            .map(|r| r.iter().filter_map(Value::as_str).collect())
            .unwrap_or_default();
        for (name, sub) in props {
            let p = if path.is_empty() {
                name.clone()
            } else {
                format!("{path}.{name}")
            };
            let ptr = format!(
                "{pointer}/properties/{}",
                name.replace('~', "~0").replace('/', "~1")
            );
            out.push(Field {
                path: p.clone(),
                pointer: ptr.clone(),
                required: required.contains(&name.as_str()),
            });
            walk(root, sub, &ptr, &p, out, depth + 1);
        }
    }
}

/// Whether the field path `path` (with `[]` markers) ends with the limit's field path
/// ("material.density" is below any owner of a material).
fn names(path: &str, limit_field: &str) -> bool {
    let segments: Vec<&str> = path.split('.').map(|s| s.trim_end_matches("[]")).collect();
    let want: Vec<&str> = limit_field.split('.').collect();
    segments.len() >= want.len() && segments[segments.len() - want.len()..] == want[..]
}

/// Applies `set` to the schema of every field the limit's path names; false when none.
fn apply(
    schema: &mut Value,
    fields: &[Field],
    limit: &str,
    set: impl Fn(&mut Map<String, Value>),
) -> bool {
    let mut any = false;
    for f in fields.iter().filter(|f| names(&f.path, limit)) {
        if let Some(s) = schema
            .pointer_mut(&f.pointer)
            .and_then(Value::as_object_mut)
        {
            set(s);
            any = true;
        }
    }
    any
}

fn set_range(s: &mut Map<String, Value>, r: &Range) {
    s.insert("minimum".into(), json!(r.min));
    s.insert("maximum".into(), json!(r.max));
}

fn set_bound(s: &mut Map<String, Value>, b: &Bound) {
    let integer = s.get("type").is_some_and(|t| {
        t == "integer" || t.as_array().is_some_and(|a| a.contains(&json!("integer")))
    });
    let number = |v: f64| if integer { json!(v as i64) } else { json!(v) };
    for (limit, exclusive, inclusive_key, exclusive_key) in [
        (b.min, b.min_exclusive, "minimum", "exclusiveMinimum"),
        (b.max, b.max_exclusive, "maximum", "exclusiveMaximum"),
    ] {
        if let Some(v) = limit {
            s.remove(inclusive_key);
            s.remove(exclusive_key);
            let key = if exclusive {
                exclusive_key
            } else {
                inclusive_key
            };
            s.insert(key.into(), number(v));
        }
    }
}

/// Units the doc comments give, in parentheses: "(m)", "(kg/m^3)", "(m/s, the same ...)", "(-)"
/// for dimensionless numbers.
const UNITS: &[&str] = &[
    "m", "s", "Pa", "kg/m^3", "kg/m3", "m/s", "m/s^2", "1/s", "rad/s", "rad", "deg", "N", "-",
];

/// The unit a description gives: the first parenthesis that opens with one of `UNITS`.
pub fn unit_of(description: &str) -> Option<&'static str> {
    let mut rest = description;
    while let Some(open) = rest.find('(') {
        // "v(s)", "vy(, vz)": a function or a list, not a unit (a unit's parenthesis follows a
        // space or opens the text).
        let call = rest[..open]
            .chars()
            .next_back()
            .is_some_and(|c| !c.is_whitespace());
        rest = &rest[open + 1..];
        if call {
            continue;
        }
        let inside = rest.split([')', ',', ';']).next().unwrap_or("").trim();
        if let Some(&u) = UNITS.iter().find(|u| **u == inside) {
            return Some(if u == "kg/m3" { "kg/m^3" } else { u });
        }
    }
    None
}

/// The schema a field's schema stands for: itself, or what its `$ref` (alone or as the one
/// entry of `allOf`) points to.
fn resolve<'a>(root: &'a Value, s: &'a Value) -> &'a Value {
    if let Some(r) = s.get("$ref").and_then(Value::as_str) {
        return root.pointer(r.trim_start_matches('#')).unwrap_or(s);
    }
    if let Some([one]) = s.get("allOf").and_then(Value::as_array).map(Vec::as_slice) {
        return resolve(root, one);
    }
    s
}

/// Whether a field holds real numbers: a number, an optional one, an array of them, or a choice
/// of which one does (the reference page gives a unit only to these).
pub fn holds_numbers(root: &Value, s: &Value) -> bool {
    let s = resolve(root, s);
    let number =
        |t: &Value| t == "number" || t.as_array().is_some_and(|a| a.contains(&json!("number")));
    s.get("type").is_some_and(number)
        || s.get("items").is_some_and(|i| holds_numbers(root, i))
        || ["anyOf", "oneOf"].iter().any(|k| {
            s.get(*k)
                .and_then(Value::as_array)
                .is_some_and(|l| l.iter().any(|x| holds_numbers(root, x)))
        })
}

/// The description of a field: its own, else that of the type it refers to.
pub fn description(root: &Value, s: &Value) -> String {
    s.get("description")
        .or_else(|| resolve(root, s).get("description"))
        .and_then(Value::as_str)
        .unwrap_or("")
        .to_string()
}

/// A short type name: "number", "array of number", "Region", `"x" | "y"`, "number or null".
pub fn type_text(root: &Value, s: &Value) -> String {
    if let Some(r) = s.get("$ref").and_then(Value::as_str) {
        let name = r.rsplit('/').next().unwrap_or(r);
        let target = resolve(root, s);
        if let Some(values) = enum_values(target) {
            return values;
        }
        return format!("[{name}](#{})", name.to_lowercase());
    }
    for key in ["allOf", "anyOf", "oneOf"] {
        if let Some(list) = s.get(key).and_then(Value::as_array) {
            if let Some(values) = enum_values(s) {
                return values;
            }
            let parts: Vec<String> = list.iter().map(|x| type_text(root, x)).collect();
            return parts.join(" or ");
        }
    }
    if let Some(values) = enum_values(s) {
        return values;
    }
    let types: Vec<String> = match s.get("type") {
        Some(Value::String(t)) => vec![t.clone()],
        Some(Value::Array(a)) => a
            .iter()
            .filter_map(Value::as_str)
            .map(String::from)
            .collect(),
        _ => vec![],
    };
    let mut parts: Vec<String> = Vec::new();
    for t in types {
        if t == "array" {
            let item = s
                .get("items")
                .map(|i| type_text(root, i))
                .unwrap_or_default();
            let n = match (s.get("minItems"), s.get("maxItems")) {
                (Some(a), Some(b)) if a == b => format!("{a} × "),
                _ => String::new(),
            };
            parts.push(format!("array of {n}{item}"));
        } else {
            parts.push(t);
        }
    }
    if parts.is_empty() {
        "any".into()
    } else {
        parts.join(" or ")
    }
}

/// `"a" | "b"` when the schema is an enumeration of strings (plain or one `const` per variant).
fn enum_values(s: &Value) -> Option<String> {
    let values: Vec<Value> = if let Some(e) = s.get("enum").and_then(Value::as_array) {
        e.clone()
    } else {
        let list = s.get("oneOf").and_then(Value::as_array)?;
        let mut v = Vec::new();
        for x in list {
            if let Some(c) = x.get("const") {
                v.push(c.clone());
            } else if let Some([c]) = x.get("enum").and_then(Value::as_array).map(Vec::as_slice) {
                v.push(c.clone());
            } else {
                return None;
            }
        }
        v
    };
    Some(
        values
            .iter()
            .map(|v| format!("`{v}`"))
            .collect::<Vec<_>>()
            .join(" | "),
    )
}

/// The range of a field as text: "[1e-3, 1e5]", "(1, 4]", "> 0", "".
pub fn range_text(s: &Value) -> String {
    let get = |k: &str| s.get(k).and_then(Value::as_f64);
    let lower = get("exclusiveMinimum")
        .map(|v| ("(", v))
        .or_else(|| get("minimum").map(|v| ("[", v)));
    let upper = get("exclusiveMaximum")
        .map(|v| (")", v))
        .or_else(|| get("maximum").map(|v| ("]", v)));
    match (lower, upper) {
        (Some((a, x)), Some((b, y))) => format!("{a}{}, {}{b}", num(x), num(y)),
        (Some(("(", x)), None) => format!("> {}", num(x)),
        (Some((_, x)), None) => format!(">= {}", num(x)),
        (None, Some((")", y))) => format!("< {}", num(y)),
        (None, Some((_, y))) => format!("<= {}", num(y)),
        (None, None) => String::new(),
    }
}

/// `{"table": ...}` for a variant of an externally tagged enumeration (an object of one required
/// property).
fn externally_tagged(v: &Value) -> Option<String> {
    let props = v.get("properties")?.as_object()?;
    match props.keys().collect::<Vec<_>>()[..] {
        [key] => Some(format!("`{{\"{key}\": ...}}`")),
        _ => None,
    }
}

/// One line of text for a Markdown table cell.
fn cell(text: &str) -> String {
    text.split_whitespace()
        .collect::<Vec<_>>()
        .join(" ")
        .replace('|', "\\|")
}

/// docs/scene-reference.md: every field of the scene (path, type, unit, range, default,
/// description) and the choices of every enumeration, from the schema.
pub fn reference_markdown() -> String {
    let schema = scene_schema();
    let mut md = String::new();
    md.push_str(
        "<!-- Generated by `mps schema --markdown` from the scene types (src/scene, \
         src/physics/params.rs) and src/scene/limits.rs; tests/suite/scene_schema.rs checks it \
         is fresh (regenerate: `cargo run --release -- schema --markdown > docs/scene-reference.md`). -->\n\
         # Scene reference\n\n\
         A scene is a JSON (or TOML) file: the bodies as boxes of particles, their materials, the \
         boundary groups and load regions, probes and the run's settings. This page lists every \
         field; the same facts are in the JSON Schema [`schema/scene.schema.json`](../schema/scene.schema.json), \
         which editors use to complete and check a scene that starts with\n\n\
         ```json\n\"$schema\": \"../schema/scene.schema.json\",\n```\n\n\
         (the path relative to the scene file; `mps` ignores the key). `mps run` checks every field \
         again and names the field of any error. `[]` in a path marks the elements of an array; \
         *required* fields have no default. Ranges: `[a, b]` includes both ends, `(a, b]` \
         excludes a, `> 0` is any positive number.\n\n",
    );
    md.push_str("## Fields\n\n| Field | Type | Unit | Range | Default | Description |\n|---|---|---|---|---|---|\n");
    for f in fields(&schema) {
        if f.path == SCHEMA_KEY {
            continue;
        }
        let s = schema
            .pointer(&f.pointer)
            .expect("a field's pointer resolves");
        let description = description(&schema, s);
        let default = match s.get("default") {
            Some(Value::Object(m)) if !m.is_empty() => "its fields' defaults".into(),
            Some(d) => format!("`{}`", serde_json::to_string(d).expect("JSON")),
            None if f.required => "*required*".into(),
            None => String::new(),
        };
        md.push_str(&format!(
            "| `{}` | {} | {} | {} | {} | {} |\n",
            f.path,
            cell(&type_text(&schema, s)),
            if holds_numbers(&schema, s) {
                unit_of(&description).unwrap_or("")
            } else {
                ""
            },
            range_text(s),
            cell(&default),
            cell(&description)
        ));
    }
    md.push_str("\n## Types and choices\n\n");
    let defs = schema
        .get("definitions")
        .and_then(Value::as_object)
        .cloned()
        .unwrap_or_default();
    for (name, def) in &defs {
        md.push_str(&format!(
            "### {name}\n\n{}\n\n",
            description(&schema, def).trim()
        ));
        if let Some(list) = def
            .get("oneOf")
            .or_else(|| def.get("anyOf"))
            .and_then(Value::as_array)
        {
            for v in list {
                let value = v
                    .get("const")
                    .or_else(|| v.get("enum").and_then(|e| e.get(0)))
                    .map(|c| format!("`{c}`"))
                    .or_else(|| externally_tagged(v))
                    .unwrap_or_else(|| type_text(&schema, v));
                md.push_str(&format!("- {value}: {}\n", cell(&description(&schema, v))));
            }
            md.push('\n');
        }
    }
    md
}

/// A deserializer that passes over a top-level [`SCHEMA_KEY`] entry of the object it reads and
/// forwards everything else unchanged (positions and field paths of errors included): a scene
/// file may name its schema for editors while `Scene` keeps refusing unknown fields.
pub(crate) struct SkipSchemaKey<D>(pub D);

/// The visitor of the top-level object: hands the inner visitor a map without the key.
struct SkipVisitor<V>(V);

/// The top-level object's entries without [`SCHEMA_KEY`].
struct SkipMap<A>(A);

impl<'de, D: de::Deserializer<'de>> de::Deserializer<'de> for SkipSchemaKey<D> {
    type Error = D::Error;

    fn deserialize_any<V: de::Visitor<'de>>(self, v: V) -> Result<V::Value, D::Error> {
        self.0.deserialize_any(SkipVisitor(v))
    }
    fn deserialize_map<V: de::Visitor<'de>>(self, v: V) -> Result<V::Value, D::Error> {
        self.0.deserialize_map(SkipVisitor(v))
    }
    fn deserialize_struct<V: de::Visitor<'de>>(
        self,
        name: &'static str,
        fields: &'static [&'static str],
        v: V,
    ) -> Result<V::Value, D::Error> {
        self.0.deserialize_struct(name, fields, SkipVisitor(v))
    }
    fn is_human_readable(&self) -> bool {
        self.0.is_human_readable()
    }
    serde::forward_to_deserialize_any! {
        bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 f32 f64 char str string bytes byte_buf
        option unit unit_struct newtype_struct seq tuple tuple_struct enum identifier
        ignored_any
    }
}

impl<'de, V: de::Visitor<'de>> de::Visitor<'de> for SkipVisitor<V> {
    type Value = V::Value;

    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        self.0.expecting(f)
    }
    fn visit_map<A: de::MapAccess<'de>>(self, map: A) -> Result<V::Value, A::Error> {
        self.0.visit_map(SkipMap(map))
    }
    fn visit_seq<A: de::SeqAccess<'de>>(self, seq: A) -> Result<V::Value, A::Error> {
        self.0.visit_seq(seq)
    }
}

impl<'de, A: de::MapAccess<'de>> de::MapAccess<'de> for SkipMap<A> {
    type Error = A::Error;

    fn next_key_seed<K: de::DeserializeSeed<'de>>(
        &mut self,
        seed: K,
    ) -> Result<Option<K::Value>, A::Error> {
        loop {
            match self.0.next_key::<String>()? {
                None => return Ok(None),
                Some(k) if k == SCHEMA_KEY => {
                    self.0.next_value::<de::IgnoredAny>()?;
                }
                Some(k) => {
                    return seed
                        .deserialize(de::value::StringDeserializer::<A::Error>::new(k))
                        .map(Some)
                }
            }
        }
    }
    fn next_value_seed<S: de::DeserializeSeed<'de>>(
        &mut self,
        seed: S,
    ) -> Result<S::Value, A::Error> {
        self.0.next_value_seed(seed)
    }
    fn size_hint(&self) -> Option<usize> {
        self.0.size_hint()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn units_are_read_from_doc_comments() {
        assert_eq!(unit_of("Density rho (kg/m^3)."), Some("kg/m^3"));
        assert_eq!(
            unit_of("`[vx, vy(, vz)]` (m/s, the same for every particle)"),
            Some("m/s")
        );
        assert_eq!(
            unit_of("Poisson's ratio nu (-), in [-0.999, 0.499]"),
            Some("-")
        );
        assert_eq!(
            unit_of("Eq. (46) with this T (s): the full vector"),
            Some("s")
        );
        assert_eq!(unit_of("Short identifier"), None);
        assert_eq!(
            unit_of("A table v(s) of the component (m/s) over s (m)"),
            Some("m/s")
        );
        assert_eq!(unit_of("f(s) = cosh ks"), None);
    }

    #[test]
    fn limit_paths_match_at_segment_boundaries() {
        assert!(names("bodies[].material.density", "material.density"));
        assert!(names("solver.dt", "solver.dt"));
        assert!(!names("solver.dt", "dt.solver"));
        assert!(!names("bodies[].material.xdensity", "material.density"));
    }
}
