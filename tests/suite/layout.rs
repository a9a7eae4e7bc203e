//! The shape of the source tree that ARCHITECTURE.md describes, kept true: the library's layers
//! depend one way (physics <- scene <- sim <- runner <- output <- fmi, studies on top), no two
//! modules of one parent import each other in a circle, and no file of src/physics or src/fmi
//! reaches 900 lines. Read from the source text (`use` items and `crate::`/`super::` paths).
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The library's top-level modules, lowest layer first: each may use only those before it.
const LAYERS: &[&str] = &[
    "physics", "scene", "sim", "runner", "output", "fmi", "studies",
];

/// Longest file (lines) allowed in src/physics and src/fmi (the team's rule).
const MAX_LINES: usize = 900;

fn src() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("src")
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().path()) {
        if e.is_dir() {
            rust_files(&e, out);
        } else if e.extension().is_some_and(|x| x == "rs") {
            out.push(e);
        }
    }
}

/// The module path of a library file: src/physics/world/mod.rs -> [physics, world].
fn module_of(file: &Path) -> Vec<String> {
    let rel = file.strip_prefix(src()).unwrap().with_extension("");
    let mut m: Vec<String> = rel
        .components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect();
    if m.last().is_some_and(|l| l == "mod" || l == "lib") {
        m.pop();
    }
    m
}

/// The code of a file without comments and the text of string and char literals.
fn code(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let b = text.as_bytes();
    let mut i = 0;
    while i < b.len() {
        if b[i..].starts_with(b"//") {
            while i < b.len() && b[i] != b'\n' {
                i += 1;
            }
        } else if b[i..].starts_with(b"/*") {
            i += 2;
            while i + 1 < b.len() && !b[i..].starts_with(b"*/") {
                i += 1;
            }
            i += 2;
        } else if b[i] == b'r'
            && (i == 0 || !(b[i - 1].is_ascii_alphanumeric() || b[i - 1] == b'_'))
            && b[i + 1..].starts_with(b"#")
        {
            // A raw string r#"..."# (any number of #), or an identifier starting with r.
            let hashes = b[i + 1..].iter().take_while(|&&c| c == b'#').count();
            if b.get(i + 1 + hashes) == Some(&b'"') {
                let close = format!("\"{}", "#".repeat(hashes));
                let body = i + 2 + hashes;
                i = text[body..]
                    .find(&close)
                    .map_or(b.len(), |k| body + k + close.len());
                out.push_str("\"\"");
            } else {
                out.push('r');
                i += 1;
            }
        } else if b[i] == b'"' {
            // A string literal.
            i += 1;
            while i < b.len() && b[i] != b'"' {
                if b[i] == b'\\' {
                    i += 1;
                }
                i += 1;
            }
            i += 1;
            out.push_str("\"\"");
        } else if b[i] == b'\'' {
            // A char literal ('"', '\n', '\'', 'é') or a lifetime ('a), which is kept.
            let mut j = i + 1;
            if b.get(j) == Some(&b'\\') {
                j += 2;
            } else {
                j += 1;
                while j < b.len() && (b[j] & 0xC0) == 0x80 {
                    j += 1;
                }
            }
            while b
                .get(j)
                .is_some_and(|c| c.is_ascii_hexdigit() || *c == b'{' || *c == b'}')
                && b[i + 1] == b'\\'
            {
                j += 1; // '\u{1F600}', '\x7f'
            }
            if b.get(j) == Some(&b'\'') {
                out.push_str("' '");
                i = j + 1;
            } else {
                out.push('\'');
                i += 1;
            }
        } else {
            // Whole UTF-8 characters (identifiers and punctuation are ASCII).
            let len = text[i..].chars().next().map_or(1, char::len_utf8);
            out.push_str(&text[i..i + len]);
            i += len;
        }
    }
    out
}

/// The code without its test modules (`#[cfg(test)] mod tests { .. }`, also
/// `#[cfg(all(test, feature = ..))]`): they may use anything, the study builders included. Also
/// the names of test modules kept in files of their own (`#[cfg(test)] mod tests;`).
fn without_tests(code: &str) -> (String, Vec<String>) {
    let mut out = String::new();
    let mut files = Vec::new();
    let mut rest = code;
    while let Some(k) = rest.find("#[cfg(") {
        let attr_end = rest[k..].find(']').map_or(rest.len(), |e| k + e + 1);
        let attr = &rest[k..attr_end];
        let after = rest[attr_end..].trim_start();
        let decl = after
            .strip_prefix("pub(crate) mod ")
            .or_else(|| after.strip_prefix("pub mod "))
            .or_else(|| after.strip_prefix("mod "));
        let (Some(decl), true) = (decl, attr.contains("test")) else {
            out.push_str(&rest[..attr_end]);
            rest = &rest[attr_end..];
            continue;
        };
        out.push_str(&rest[..k]);
        let name_len = decl
            .find(|c: char| !(c.is_alphanumeric() || c == '_'))
            .unwrap_or(decl.len());
        let name = &decl[..name_len];
        let tail = decl[name_len..].trim_start();
        if let Some(body) = tail.strip_prefix('{') {
            let mut depth = 1;
            let mut end = body.len();
            for (i, c) in body.char_indices() {
                match c {
                    '{' => depth += 1,
                    '}' => {
                        depth -= 1;
                        if depth == 0 {
                            end = i + 1;
                            break;
                        }
                    }
                    _ => {}
                }
            }
            rest = &body[end..];
        } else {
            files.push(name.to_string());
            rest = tail.strip_prefix(';').unwrap_or(tail);
        }
    }
    out.push_str(rest);
    (out, files)
}

/// Expands `a::{b, c::{d, e}}` into [a::b, a::c::d, a::c::e].
fn expand(tree: &str) -> Vec<String> {
    let tree = tree.trim();
    let Some(open) = tree.find('{') else {
        return vec![tree.split(" as ").next().unwrap().trim().to_string()];
    };
    let prefix = &tree[..open];
    let inner = &tree[open + 1..tree.rfind('}').expect("a closing brace")];
    let mut parts = Vec::new();
    let (mut depth, mut start) = (0, 0);
    for (k, c) in inner.char_indices() {
        match c {
            '{' => depth += 1,
            '}' => depth -= 1,
            ',' if depth == 0 => {
                parts.push(&inner[start..k]);
                start = k + 1;
            }
            _ => {}
        }
    }
    parts.push(&inner[start..]);
    parts
        .into_iter()
        .filter(|p| !p.trim().is_empty())
        .flat_map(expand)
        .map(|p| format!("{prefix}{p}"))
        .collect()
}

/// The crate-absolute module paths a file refers to: its `use` items and every
/// `crate::`/`super::`/`self::` path in its code.
fn references(file: &Path) -> Vec<Vec<String>> {
    let text = without_tests(&code(&std::fs::read_to_string(file).unwrap())).0;
    let module = module_of(file);
    let mut paths = Vec::new();
    let mut rest = text.as_str();
    while let Some(k) = rest.find("use ") {
        let before = rest[..k].chars().last();
        rest = &rest[k + 4..];
        if before.is_some_and(|c| c.is_alphanumeric() || c == '_') {
            continue;
        }
        let end = rest.find(';').unwrap_or(rest.len());
        paths.extend(expand(&rest[..end]));
    }
    let b = text.as_bytes();
    for start in ["crate::", "super::", "self::"] {
        for (k, _) in text.match_indices(start) {
            if k > 0 && (b[k - 1].is_ascii_alphanumeric() || b[k - 1] == b'_' || b[k - 1] == b':') {
                continue;
            }
            let end = text[k..]
                .find(|c: char| !(c.is_alphanumeric() || c == '_' || c == ':'))
                .map_or(text.len(), |e| k + e);
            paths.push(text[k..end].trim_end_matches(':').to_string());
        }
    }
    let mut out = Vec::new();
    for p in paths {
        let mut seg: Vec<&str> = p.split("::").filter(|s| !s.is_empty()).collect();
        // `self`/`super` start from the file's module (a mod.rs file is its directory's).
        let mut base = module.clone();
        match seg.first().copied() {
            Some("crate") => {
                base.clear();
                seg.remove(0);
            }
            Some("self") => {
                seg.remove(0);
            }
            Some("super") => {
                while seg.first() == Some(&"super") {
                    base.pop();
                    seg.remove(0);
                }
            }
            _ => continue, // an external crate, std, or a path relative to a local name
        }
        base.extend(seg.iter().map(|s| s.to_string()));
        out.push(base);
    }
    out
}

struct Tree {
    /// Every module of the library (files and directories).
    modules: BTreeSet<Vec<String>>,
    /// Module -> the modules it refers to (the longest module prefix of each path).
    uses: BTreeMap<Vec<String>, BTreeSet<Vec<String>>>,
}

fn tree() -> Tree {
    let mut files = Vec::new();
    rust_files(&src(), &mut files);
    files.retain(|f| !f.starts_with(src().join("bin")));
    // Test modules in files of their own are left out, as test modules inside files are.
    let mut tests: Vec<Vec<String>> = Vec::new();
    for f in &files {
        let code = code(&std::fs::read_to_string(f).unwrap());
        for name in without_tests(&code).1 {
            let mut m = module_of(f);
            m.push(name);
            tests.push(m);
        }
    }
    files.retain(|f| {
        let m = module_of(f);
        !tests.iter().any(|t| m.starts_with(t))
    });
    let modules: BTreeSet<Vec<String>> = files.iter().map(|f| module_of(f)).collect();
    let mut uses = BTreeMap::new();
    for f in &files {
        let from = module_of(f);
        let set: BTreeSet<Vec<String>> = references(f)
            .into_iter()
            .filter_map(|p| {
                (0..=p.len())
                    .rev()
                    .map(|n| p[..n].to_vec())
                    .find(|m| modules.contains(m) && !m.is_empty())
            })
            .filter(|m| m != &from)
            .collect();
        uses.insert(from, set);
    }
    Tree { modules, uses }
}

#[test]
fn layers_depend_one_way() {
    let t = tree();
    let mut wrong = Vec::new();
    for (from, to) in &t.uses {
        let Some(layer) = LAYERS
            .iter()
            .position(|l| from.first().is_some_and(|f| f == l))
        else {
            continue;
        };
        for m in to {
            let Some(other) = LAYERS.iter().position(|l| m[0] == *l) else {
                continue;
            };
            if other > layer {
                wrong.push(format!("{} uses {}", from.join("::"), m.join("::")));
            }
        }
    }
    assert!(
        wrong.is_empty(),
        "a lower layer uses a higher one (order: {LAYERS:?}):\n{}",
        wrong.join("\n")
    );
    // The test sees the layers at all: physics is used by scene.
    assert!(t.uses[&vec!["scene".to_string()]]
        .iter()
        .any(|m| m[0] == "physics"));
}

/// The sibling a reference lands in: for `from` = a::b::f and `to` = a::b::x::y, a::b::x.
fn sibling(from: &[String], to: &[String]) -> Option<Vec<String>> {
    let parent = &from[..from.len().checked_sub(1)?];
    if to.len() > parent.len()
        && to[..parent.len()] == *parent
        && to[parent.len()] != from[parent.len()]
    {
        Some(to[..=parent.len()].to_vec())
    } else {
        None
    }
}

/// Cycles of the graph "module uses a sibling (or something inside it)": each cycle once, as
/// the module names along it.
fn sibling_cycles(t: &Tree) -> Vec<String> {
    let mut edges: BTreeMap<Vec<String>, BTreeSet<Vec<String>>> = BTreeMap::new();
    for (from, to) in &t.uses {
        // A module's uses include those of the files inside it (a directory module).
        for (anc_len, _) in from.iter().enumerate() {
            let anc = from[..=anc_len].to_vec();
            for m in to {
                if let Some(s) = sibling(&anc, m) {
                    edges.entry(anc.clone()).or_default().insert(s);
                }
            }
        }
    }
    let mut cycles = BTreeSet::new();
    for start in edges.keys() {
        // Depth-first search for a path back to start.
        let mut stack = vec![(start.clone(), vec![start.clone()])];
        let mut seen = BTreeSet::new();
        while let Some((node, path)) = stack.pop() {
            for next in edges.get(&node).into_iter().flatten() {
                if next == start {
                    let mut names: Vec<String> = path.iter().map(|m| m.join("::")).collect();
                    let min = names
                        .iter()
                        .enumerate()
                        .min_by_key(|(_, n)| (*n).clone())
                        .unwrap()
                        .0;
                    names.rotate_left(min);
                    cycles.insert(names.join(" -> "));
                } else if seen.insert(next.clone()) {
                    let mut p = path.clone();
                    p.push(next.clone());
                    stack.push((next.clone(), p));
                }
            }
        }
    }
    cycles.into_iter().collect()
}

#[test]
fn no_two_modules_import_each_other() {
    let t = tree();
    assert!(
        t.modules.len() > 40,
        "the walk found only {} modules",
        t.modules.len()
    );
    let cycles = sibling_cycles(&t);
    assert!(cycles.is_empty(), "import circles:\n{}", cycles.join("\n"));
}

#[test]
fn the_cycle_check_finds_a_circle() {
    // Two siblings that use each other, as physics/elastic.rs and physics/second_order.rs
    // once did: the check must report them.
    let m = |s: &str| s.split("::").map(String::from).collect::<Vec<_>>();
    let mut t = Tree {
        modules: [m("physics::a"), m("physics::b"), m("physics::c")].into(),
        uses: BTreeMap::new(),
    };
    t.uses.insert(m("physics::a"), [m("physics::b")].into());
    t.uses.insert(m("physics::b"), [m("physics::c")].into());
    assert!(sibling_cycles(&t).is_empty());
    t.uses.insert(m("physics::c"), [m("physics::a")].into());
    assert_eq!(
        sibling_cycles(&t),
        ["physics::a -> physics::b -> physics::c"]
    );
}

#[test]
fn test_modules_are_left_out() {
    let (code, files) = without_tests(
        "use crate::a;\n#[cfg(all(test, feature = \"studies\"))]\nmod range_tests {\n    use crate::studies::x;\n    fn f() { {} }\n}\nfn g() {}\n#[cfg(test)]\nmod tests;\n#[cfg(feature = \"parallel\")]\nuse crate::b;\n",
    );
    assert!(
        !code.contains("studies") && code.contains("fn g()") && code.contains("crate::b"),
        "{code}"
    );
    assert_eq!(files, ["tests"]);
}

#[test]
fn use_trees_expand() {
    assert_eq!(
        expand("super::{limits::num,velocity::{self,Omega}}"),
        [
            "super::limits::num",
            "super::velocity::self",
            "super::velocity::Omega"
        ]
    );
    assert_eq!(
        expand("crate::physics::Material as M"),
        ["crate::physics::Material"]
    );
}

#[test]
fn physics_and_fmi_files_stay_short() {
    let mut files = Vec::new();
    rust_files(&src().join("physics"), &mut files);
    rust_files(&src().join("fmi"), &mut files);
    assert!(files.len() > 20);
    let long: Vec<String> = files
        .iter()
        .map(|f| (f, std::fs::read_to_string(f).unwrap().lines().count()))
        .filter(|(_, n)| *n >= MAX_LINES)
        .map(|(f, n)| format!("{}: {n} lines", f.display()))
        .collect();
    assert!(
        long.is_empty(),
        "files of {MAX_LINES} lines or more:\n{}",
        long.join("\n")
    );
}
