//! Builds `NAME.fmu` from a scene and the built cdylib: modelDescription.xml,
//! binaries/linux64/<modelIdentifier>.so, resources/scene.json (with the STL files of its
//! meshes beside it, and the default operator's closure as the packing computed it:
//! resources/mps-closure.bin), documentation/index.html.
use super::model_description::guid;
use super::variables::{coordinate, point, VarType, VariableTable};
use crate::scene::limits::num;
use crate::scene::Scene;
use std::io::Write;
use std::path::Path;
use zip::write::SimpleFileOptions;
use zip::{CompressionMethod, ZipWriter};

/// The modelDescription.xml of a scene's FMU (of its packed form, [`packed_scene`]).
pub fn model_description_xml(scene: &Scene) -> String {
    super::model_description::model_description_xml(&packed_scene(scene).0)
}

/// Every mesh shape of a scene (bodies' shapes and cuts, boundaries' and loads' selections).
fn meshes_mut(scene: &mut Scene) -> Vec<&mut crate::scene::MeshSpec> {
    use crate::scene::Shape;
    let mut out = Vec::new();
    for b in &mut scene.bodies {
        for s in b.shapes.iter_mut().chain(b.cuts.iter_mut()) {
            if let Shape::Mesh(m) = s {
                out.push(m);
            }
        }
    }
    for s in scene
        .boundaries
        .iter_mut()
        .filter_map(|g| g.shape.as_mut())
        .chain(scene.loads.iter_mut().filter_map(|l| l.shape.as_mut()))
    {
        if let Shape::Mesh(m) = s {
            out.push(m);
        }
    }
    out
}

/// The scene as an FMU holds it, and the files to put into its resources folder (path in the
/// archive below `resources/`, file on disk). A mesh named by a plain relative path
/// ("bracket.stl", "parts/bracket.stl") keeps it; any other ("../x.stl", "/abs/x.stl") becomes
/// "meshes/<k>_<file name>", k its rank among the meshes.
pub fn packed_scene(scene: &Scene) -> (Scene, Vec<(String, std::path::PathBuf)>) {
    let mut packed = scene.clone();
    let base = scene.base_dir.clone();
    let mut files: Vec<(String, std::path::PathBuf)> = Vec::new();
    for (k, m) in meshes_mut(&mut packed).into_iter().enumerate() {
        let source = crate::scene::shape::mesh_path(base.as_deref(), &m.file);
        let p = Path::new(&m.file);
        let plain = p.is_relative()
            && p.components()
                .all(|c| matches!(c, std::path::Component::Normal(_)))
            && m.file != "scene.json"
            && m.file != super::instance::CLOSURE_FILE;
        let name = if plain {
            m.file.clone()
        } else {
            let file = p
                .file_name()
                .map(|f| f.to_string_lossy().into_owned())
                .unwrap_or_else(|| "mesh.stl".into());
            format!("meshes/{k}_{file}")
        };
        m.file = name.clone();
        if !files.iter().any(|(n, _)| *n == name) {
            files.push((name, source));
        }
    }
    (packed, files)
}

fn html(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// "1 body", "2 bodies".
fn count(n: usize, one: &str, many: &str) -> String {
    format!("{n} {}", if n == 1 { one } else { many })
}

/// A value of a variable for the page: an Integer as an integer, a Real in its shortest form.
fn value(ty: VarType, x: f64) -> String {
    match ty {
        VarType::Integer => format!("{}", x as i64),
        VarType::Real => num(x),
    }
}

/// A region's extent as "[x0, x1] x [y0, y1] (x [z0, z1])" (m).
fn extent(min: &[f64], max: &[f64]) -> String {
    min.iter()
        .zip(max)
        .map(|(a, b)| format!("[{}, {}]", coordinate(*a), coordinate(*b)))
        .collect::<Vec<_>>()
        .join(" &times; ")
}

/// A selection's region and shape for the documentation.
fn selection(r: &crate::scene::Region, s: Option<&crate::scene::Shape>) -> String {
    let shape = s.map(|s| {
        html(
            &serde_json::to_string(s)
                .unwrap_or_default()
                .replace(",\"", ", \""),
        )
    });
    match (r.min.is_empty(), shape) {
        (true, Some(s)) => s,
        (false, Some(s)) => format!("{} and {s}", extent(&r.min, &r.max)),
        (_, None) => extent(&r.min, &r.max),
    }
}

/// documentation/index.html: the scene, its coupling regions (with the particle counts of the
/// built model `sim`) and every variable.
pub fn documentation_html(scene: &Scene, sim: &crate::sim::Simulation) -> String {
    let table = VariableTable::new(scene);
    let mut s = String::new();
    s.push_str("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n");
    s.push_str(&format!("<title>{}</title>\n", html(&scene.name)));
    s.push_str("<style>body{font-family:sans-serif;max-width:70em;margin:auto}table{border-collapse:collapse}td,th{border:1px solid #999;padding:0.2em 0.5em;vertical-align:top}</style>\n</head>\n<body>\n");
    s.push_str(&format!(
        "<h1>{}</h1>\n<p>FMI 2.0 Co-Simulation FMU generated by mps-solid {} (GUID {}): an MPS \
         particle model of elastic solids in {}D, {}.</p>\n<p>{}</p>\n",
        html(&scene.name),
        env!("CARGO_PKG_VERSION"),
        guid(scene),
        scene.dimension,
        count(scene.bodies.len(), "body", "bodies"),
        html(&scene.description)
    ));
    s.push_str(&format!(
        "<p>Default experiment: 0 to {} s with a communication step of {} s. Each fmi2DoStep is \
         split into equal solver steps no longer than the stable step and lands exactly on t + h. \
         Parameters can be set until fmi2ExitInitializationMode; the model is built (or rebuilt) \
         from them then. The FMU state (fmi2GetFMUstate, serialisation) is portable data.</p>\n",
        num(scene.end_time),
        num(scene.output_interval)
    ));
    let per = if scene.dimension == 2 {
        " per metre of depth (plane strain: a 2D scene is a slice of unit thickness)"
    } else {
        ""
    };
    s.push_str(&format!(
        "<h2>Coupling</h2>\n<p>Forces, reactions and energies are in N and J{per}. A load region's \
         force input is the total force on the region, spread evenly over its particles (all \
         particles have the same volume, so this is spreading by volume); its outputs \
         <code>.u*</code> / <code>.v*</code> are the mean displacement and velocity of exactly \
         those particles, the motion work-conjugate to the force. Inputs are held over a \
         communication step; first derivatives set with fmi2SetRealInputDerivatives \
         (canInterpolateInputs) make them linear over the next step. Boundary displacement inputs \
         act at the start of the step (boundary_input_timing = 1, FMI semantics) or are reached at \
         its end (2). Gravity comes from the scene's law (gravity_source = 1) or the inputs (2). \
         A NaN or infinite input is refused (fmi2Error); a coupled run that goes unstable stops \
         with the solver's blow-up, material-collapse or overlap error, never with NaN outputs.</p>\n"
    ));
    s.push_str("<table>\n<tr><th>Kind</th><th>Name</th><th>Body</th><th>Region or point (m)</th><th>Particles</th></tr>\n");
    for (r, l) in scene.loads.iter().enumerate() {
        s.push_str(&format!(
            "<tr><td>load region</td><td><code>{}</code></td><td>{}</td><td>{}</td><td>{}</td></tr>\n",
            html(&l.name),
            html(&l.body),
            selection(&l.region, l.shape.as_ref()),
            sim.load_size(r)
        ));
    }
    for (g, b) in scene.boundaries.iter().enumerate() {
        s.push_str(&format!(
            "<tr><td>boundary group ({:?})</td><td><code>{}</code></td><td>{}</td><td>{}</td><td>{}</td></tr>\n",
            b.kind,
            html(&b.name),
            html(&b.body),
            selection(&b.region, b.shape.as_ref()),
            sim.group_size(g)
        ));
    }
    for (k, p) in scene.probes.iter().enumerate() {
        let at = sim.probe_particle_position(k);
        s.push_str(&format!(
            "<tr><td>probe</td><td><code>{}</code></td><td>{}</td><td>{} (read at the particle \
             at {}, interpolated with the corrected gradient)</td><td>1</td></tr>\n",
            html(&p.name),
            html(
                p.body
                    .as_deref()
                    .unwrap_or("(the body containing the point)")
            ),
            point(&p.point),
            point(&at[..scene.dimension.min(3)])
        ));
    }
    s.push_str("</table>\n");
    s.push_str("<h2>Variables</h2>\n<table>\n<tr><th>#</th><th>Name</th><th>Value reference</th><th>Type</th><th>Causality</th><th>Variability</th><th>Unit</th><th>Start</th><th>Range</th><th>Description</th></tr>\n");
    for (i, v) in table.vars.iter().enumerate() {
        s.push_str(&format!(
            "<tr><td>{}</td><td><code>{}</code></td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>\n",
            i + 1,
            html(&v.name),
            v.value_reference,
            v.ty.name(),
            v.causality.name(),
            v.variability.name(),
            v.unit.unwrap_or("-"),
            v.start
                .map(|x| value(v.ty, x))
                .unwrap_or_else(|| "calculated".into()),
            match (v.min, v.max) {
                (Some(lo), Some(hi)) => format!("[{}, {}]", value(v.ty, lo), value(v.ty, hi)),
                _ => "-".into(),
            },
            html(&v.description)
        ));
    }
    s.push_str("</table>\n</body>\n</html>\n");
    s
}

/// Whether two paths name the same file (same device and inode; false when either does not
/// exist).
pub fn same_file(a: &Path, b: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (std::fs::metadata(a), std::fs::metadata(b)) {
        (Ok(x), Ok(y)) => x.dev() == y.dev() && x.ino() == y.ino(),
        _ => false,
    }
}

/// Checks that `lib` is a 64-bit little-endian ELF shared object (linux64) whose dynamic symbol
/// table defines the function `symbol` (read with the `object` crate, without loading it).
pub fn check_shared_library(lib: &[u8], symbol: &str) -> Result<(), String> {
    use object::{Object, ObjectKind, ObjectSymbol, SymbolKind};
    if lib.len() < 4 || &lib[..4] != b"\x7fELF" {
        return Err("is not an ELF shared library (no ELF header)".into());
    }
    if lib.len() < 6 || lib[4] != 2 || lib[5] != 1 {
        return Err("is not an ELF shared library for linux64 (not 64-bit little-endian)".into());
    }
    let file = object::File::parse(lib)
        .map_err(|e| format!("is a truncated or malformed ELF file ({e})"))?;
    if file.kind() != ObjectKind::Dynamic {
        return Err(format!(
            "is not an ELF shared library (an ELF file of kind {:?})",
            file.kind()
        ));
    }
    let exported = file
        .dynamic_symbols()
        .any(|s| s.name() == Ok(symbol) && s.is_definition() && s.kind() == SymbolKind::Text);
    if exported {
        Ok(())
    } else {
        Err(format!("does not export {symbol}"))
    }
}

/// The newest glibc symbol version `lib` needs (e.g. (2, 17)), read from its version needs
/// (`.gnu.version_r`, what `objdump -T` lists as GLIBC_x.y); None when it names none or `lib` is
/// not a 64-bit ELF file.
pub fn newest_glibc(lib: &[u8]) -> Option<(u32, u32)> {
    use object::read::elf::ElfFile64;
    let file = ElfFile64::<object::Endianness>::parse(lib).ok()?;
    let endian = file.endian();
    let sections = file.elf_section_table();
    let (mut needs, link) = sections.gnu_verneed(endian, lib).ok()??;
    let strings = sections.strings(endian, lib, link).ok()?;
    let mut newest = None;
    while let Ok(Some((_, mut auxs))) = needs.next() {
        while let Ok(Some(aux)) = auxs.next() {
            let Ok(name) = aux.name(endian, strings) else {
                continue;
            };
            let Some(v) = std::str::from_utf8(name)
                .ok()
                .and_then(|n| n.strip_prefix("GLIBC_"))
            else {
                continue;
            };
            let mut parts = v.split('.').map(|p| p.parse::<u32>());
            if let (Some(Ok(major)), Some(Ok(minor))) = (parts.next(), parts.next()) {
                newest = newest.max(Some((major, minor)));
            }
        }
    }
    newest
}

/// The source id a library was built from (`MPS_SOLID_SOURCE_ID`, src/fmi/source_id.rs), read
/// from its exported data without loading it; None when it has none (a library of another
/// program, or of mps-solid before the id).
pub fn library_source_id(lib: &[u8]) -> Option<String> {
    use object::{Object, ObjectSection, ObjectSymbol};
    let file = object::File::parse(lib).ok()?;
    let sym = file
        .dynamic_symbols()
        .find(|s| s.name() == Ok("MPS_SOLID_SOURCE_ID"))?;
    let section = file.section_by_index(sym.section_index()?).ok()?;
    let data = section.data().ok()?;
    let start = usize::try_from(sym.address().checked_sub(section.address())?).ok()?;
    let bytes = data.get(start..start.checked_add(usize::try_from(sym.size()).ok()?)?)?;
    let end = bytes.iter().position(|&b| b == 0).unwrap_or(bytes.len());
    String::from_utf8(bytes[..end].to_vec()).ok()
}

/// Checks that the library was built from the sources of this program (its source id is
/// [`SOURCE_ID`](super::source_id::SOURCE_ID)): the modelDescription.xml written here numbers the
/// variables as this build's table does, and the library reads its variables from its own.
pub fn check_source_id(lib: &[u8], library: &Path) -> Result<(), String> {
    let own = super::source_id::SOURCE_ID;
    match library_source_id(lib) {
        Some(id) if id == own => Ok(()),
        found => Err(format!(
            "{} was built from other sources than this mps ({}; this mps: {own}): its variable \
             table may not match the modelDescription.xml this mps writes. Rebuild the library \
             (scripts/build-fmu-lib.sh for the portable one) or this program, from the same \
             sources",
            library.display(),
            match found {
                Some(id) => format!("its source id: {id}"),
                None => "it carries no source id".to_string(),
            }
        )),
    }
}

/// Refuses an output path that names something other than a regular file: a symbolic link
/// (not followed: the FMU would replace the link, not what it points to), a directory, a named
/// pipe, a device or a socket. A missing path is fine (the FMU is a new file).
pub fn check_output_target(out: &Path) -> Result<(), String> {
    use std::os::unix::fs::FileTypeExt;
    let meta = match std::fs::symlink_metadata(out) {
        Ok(m) => m,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(format!("cannot inspect the output {}: {e}", out.display())),
    };
    let t = meta.file_type();
    if t.is_file() {
        return Ok(());
    }
    if t.is_symlink() {
        let to = std::fs::read_link(out)
            .map(|p| p.display().to_string())
            .unwrap_or_else(|e| format!("unreadable: {e}"));
        return Err(format!(
            "the output {} is a symbolic link (to {to}); mps pack follows no link: give the \
             path it points to, or remove the link",
            out.display()
        ));
    }
    let what = if t.is_dir() {
        "a directory"
    } else if t.is_fifo() {
        "a named pipe (FIFO)"
    } else if t.is_char_device() {
        "a character device"
    } else if t.is_block_device() {
        "a block device"
    } else if t.is_socket() {
        "a socket"
    } else {
        "not a regular file"
    };
    Err(format!(
        "the output {} is {what}, not a regular file: the FMU is written beside it and renamed \
         over it, which would replace it; give the path of a new or regular file (a directory \
         of FMUs is --out-dir)",
        out.display()
    ))
}

/// Builds `out` (NAME.fmu) from a scene and the built library (scripts/build-fmu-lib.sh, or
/// target/<profile>/libmps_solid.so). The output must be a new or regular file
/// ([`check_output_target`]), checked before any work and again before the rename. The scene
/// is validated and its model built (a scene that cannot initialise is refused now, not in the
/// importer); the library must be an ELF shared object exporting fmi2DoStep, built from the
/// sources of this program ([`check_source_id`]). The archive is made in memory, written to a
/// new temporary file beside `out` and renamed onto it when complete, so a failure leaves no
/// partial FMU (and an existing `out` untouched); a write error names the file and the OS
/// reason (e.g. "File too large (os error 27)").
pub fn pack_fmu(scene: &Scene, library: &Path, out: &Path) -> Result<(), String> {
    check_output_target(out)?;
    scene.validate().map_err(|e| e.to_string())?;
    if same_file(library, out) {
        return Err(format!(
            "the output {} is the library itself; choose another --out",
            out.display()
        ));
    }
    let lib = std::fs::read(library)
        .map_err(|e| format!("cannot read the library {}: {e}", library.display()))?;
    check_shared_library(&lib, "fmi2DoStep").map_err(|m| {
        format!(
            "{} {m}; give the libmps_solid.so built by scripts/build-fmu-lib.sh (or cargo build \
             --release)",
            library.display()
        )
    })?;
    check_source_id(&lib, library)?;
    // Built with a memo: the default operator's closure it computes is shipped in the
    // resources, so that an instance's first build takes it (the FMU's parameters change no
    // geometry) instead of computing it again.
    struct Keep(crate::physics::world::SetupMemo);
    impl crate::physics::world::SetupObserver for Keep {
        fn memo(&self) -> Option<&crate::physics::world::SetupMemo> {
            Some(&self.0)
        }
    }
    let keep = Keep(Default::default());
    let sim = crate::sim::Simulation::new_observed(scene, &keep)
        .map_err(|e| format!("the scene's model cannot be built: {e}"))?;
    let closure = keep.0.closure_bytes();
    let (packed, files) = packed_scene(scene);
    let mut resources = Vec::new();
    for (name, source) in files {
        let data = std::fs::read(&source)
            .map_err(|e| format!("cannot read the mesh {}: {e}", source.display()))?;
        resources.push((name, data));
    }
    let scene = &packed;
    let xml = super::model_description::packed_model_description_xml(scene)?;
    let doc = documentation_html(scene, &sim);
    drop(sim);
    if let Some(bytes) = closure {
        resources.push((super::instance::CLOSURE_FILE.to_string(), bytes));
    }
    let archive = archive(scene, &xml, &doc, &lib, &resources)
        .map_err(|e| format!("cannot make the FMU archive of {}: {e}", out.display()))?;
    drop(lib);
    replace_file(out, &archive)
}

/// Writes `data` to `out` as a whole or not at all: into a new file beside it, synced, then
/// renamed over it (an existing regular file is replaced; a link, a directory or a device is
/// refused, [`check_output_target`]). Errors name the path and the OS reason.
pub fn replace_file(out: &Path, data: &[u8]) -> Result<(), String> {
    let dir = match out.parent().filter(|d| !d.as_os_str().is_empty()) {
        Some(dir) => {
            std::fs::create_dir_all(dir)
                .map_err(|e| format!("cannot create the directory {}: {e}", dir.display()))?;
            dir.to_path_buf()
        }
        None => std::path::PathBuf::from("."),
    };
    let file_name = out
        .file_name()
        .ok_or_else(|| format!("{} does not name a file", out.display()))?;
    let tmp = dir.join(format!(
        ".{}.{}.tmp",
        file_name.to_string_lossy(),
        std::process::id()
    ));
    let result = write_new_file(&tmp, data)
        .and_then(|()| check_output_target(out))
        .and_then(|()| {
            std::fs::rename(&tmp, out)
                .map_err(|e| format!("cannot rename {} to {}: {e}", tmp.display(), out.display()))
        });
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Writes `data` into a new file `path` (refused if anything exists there, a link included)
/// and syncs it; errors name the path and the OS reason.
fn write_new_file(path: &Path, data: &[u8]) -> Result<(), String> {
    use std::os::unix::fs::OpenOptionsExt;
    let mut file = std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .mode(0o644)
        .open(path)
        .map_err(|e| format!("cannot create {}: {e}", path.display()))?;
    file.write_all(data)
        .and_then(|()| file.sync_all())
        .map_err(|e| format!("cannot write {}: {e}", path.display()))
}

/// The FMU archive (zip) in memory: nothing of it reaches a file until it is complete, and the
/// zip writer never meets an I/O error (its drop would print one).
fn archive(
    scene: &Scene,
    xml: &str,
    doc: &str,
    lib: &[u8],
    resources: &[(String, Vec<u8>)],
) -> zip::result::ZipResult<Vec<u8>> {
    type Writer = ZipWriter<std::io::Cursor<Vec<u8>>>;
    let mut z: Writer = ZipWriter::new(std::io::Cursor::new(Vec::new()));
    let opts = SimpleFileOptions::default()
        .compression_method(CompressionMethod::Deflated)
        .unix_permissions(0o644);
    let add = |z: &mut Writer, name: &str, data: &[u8], mode: u32| {
        z.start_file(name, opts.unix_permissions(mode))?;
        z.write_all(data)?;
        Ok::<(), zip::result::ZipError>(())
    };
    add(&mut z, "modelDescription.xml", xml.as_bytes(), 0o644)?;
    for d in [
        "binaries/",
        "binaries/linux64/",
        "resources/",
        "documentation/",
    ] {
        z.add_directory(d, opts.unix_permissions(0o755))?;
    }
    add(
        &mut z,
        &format!("binaries/linux64/{}.so", scene.name),
        lib,
        0o755,
    )?;
    add(
        &mut z,
        "resources/scene.json",
        scene.to_json().as_bytes(),
        0o644,
    )?;
    for (name, data) in resources {
        add(&mut z, &format!("resources/{name}"), data, 0o644)?;
    }
    add(&mut z, "documentation/index.html", doc.as_bytes(), 0o644)?;
    Ok(z.finish()?.into_inner())
}
