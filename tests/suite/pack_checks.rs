//! `mps pack` (issue 8, item 16; issue 27, items 1 and 6): only the FMU library is packed, built
//! from the same sources, the portable one by default; a scene that cannot be built or whose
//! text the modelDescription.xml cannot hold is refused, the output is never the scene nor
//! anything but a regular file (no device, pipe, directory, and no link followed), a failed write
//! leaves no partial .fmu, and IO errors name the path and the OS reason.
use crate::common;

use mps_solid::fmi::pack::{check_shared_library, pack_fmu};
use mps_solid::Scene;
use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("mps-pack-{}-{name}", std::process::id()));
    std::fs::remove_dir_all(&d).ok();
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn small2d() -> Scene {
    Scene::load(&root().join("tests/data/small2d.json")).unwrap()
}

/// Files of a directory (names).
fn listing(d: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(d)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn only_a_shared_library_exporting_fmi2dostep_is_packed() {
    let lib = std::fs::read(common::built_library()).unwrap();
    check_shared_library(&lib, "fmi2DoStep").unwrap();
    assert!(check_shared_library(&lib, "fmi2NoSuchFunction").is_err());
    // The mps program is an ELF (a position-independent executable, ET_DYN) without the FMI API.
    let exe = std::fs::read(env!("CARGO_BIN_EXE_mps")).unwrap();
    let e = check_shared_library(&exe, "fmi2DoStep").unwrap_err();
    assert!(e.contains("does not export fmi2DoStep"), "{e}");
    // Not ELF, truncated ELF, 32-bit ELF.
    assert!(check_shared_library(b"hello", "fmi2DoStep").is_err());
    let e = check_shared_library(&lib[..200], "fmi2DoStep").unwrap_err();
    assert!(e.contains("malformed") || e.contains("truncated"), "{e}");
    let mut elf32 = lib[..4096].to_vec();
    elf32[4] = 1;
    assert!(check_shared_library(&elf32, "fmi2DoStep")
        .unwrap_err()
        .contains("64-bit"));
    // Through pack_fmu: refused, nothing written.
    let d = scratch("elf");
    let out = d.join("x.fmu");
    let e = pack_fmu(&small2d(), Path::new(env!("CARGO_BIN_EXE_mps")), &out).unwrap_err();
    assert!(
        e.contains("does not export fmi2DoStep") && e.contains("mps"),
        "{e}"
    );
    assert!(listing(&d).is_empty(), "{:?}", listing(&d));
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn a_scene_that_cannot_be_built_is_refused_at_pack_time() {
    // A load region between two particle columns holds no particle: valid as a box, but the
    // model cannot be built.
    let mut s = small2d();
    s.loads[0].region.min = vec![0.2, 0.0];
    s.loads[0].region.max = vec![0.2, 0.0];
    let d = scratch("build");
    let e = pack_fmu(&s, &common::built_library(), &d.join("x.fmu")).unwrap_err();
    assert!(
        e.contains("loads[0] ('tip_load').region") && e.contains("no particle"),
        "{e}"
    );
    assert!(listing(&d).is_empty());
    // Control characters in a body name (set past the scene loader): refused, naming the field.
    let mut s = small2d();
    s.bodies[0].name = "st\u{1}rip".into();
    let e = pack_fmu(&s, &common::built_library(), &d.join("x.fmu")).unwrap_err();
    assert!(e.contains("bodies[0].name") && e.contains("U+0001"), "{e}");
    let mut s = small2d();
    s.description = "nul \u{0} here".into();
    let e = pack_fmu(&s, &common::built_library(), &d.join("x.fmu")).unwrap_err();
    assert!(e.contains("description") && e.contains("U+0000"), "{e}");
    assert!(listing(&d).is_empty());
    std::fs::remove_dir_all(&d).ok();
}

#[test]
#[ignore = "slow (21 s on a loaded 2-core machine): the full test command runs it"]
fn a_failed_write_leaves_no_partial_fmu_and_names_path_and_reason() {
    let d = scratch("write");
    let scene = root().join("tests/data/small2d.json");
    // A file-size limit makes the write fail part way (SIGXFSZ ignored: the write returns EFBIG).
    let out = d.join("small2d.fmu");
    let cmd = format!(
        "trap '' XFSZ; ulimit -f 64; exec '{}' pack '{}' --lib '{}' --out '{}'",
        env!("CARGO_BIN_EXE_mps"),
        scene.display(),
        common::built_library().display(),
        out.display()
    );
    let r = Command::new("sh").arg("-c").arg(&cmd).output().unwrap();
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(!r.status.success(), "{err}");
    // One error line with the file and the OS reason; no line of the zip writer's drop.
    assert!(
        err.contains("File too large (os error 27)") && err.contains(d.to_str().unwrap()),
        "{err}"
    );
    assert!(!err.contains("ZipWriter"), "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(listing(&d).is_empty(), "left behind: {:?}", listing(&d));
    // Without the shell ignoring SIGXFSZ: mps ignores it, so the signal does not kill it
    // half way (which would leave the temporary file) and the error is the same.
    let untrapped = cmd.replace("trap '' XFSZ; ", "");
    let r = Command::new("sh")
        .arg("-c")
        .arg(&untrapped)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(1), "{err}");
    assert!(err.contains("File too large (os error 27)"), "{err}");
    assert!(listing(&d).is_empty(), "left behind: {:?}", listing(&d));
    // An existing FMU is not touched by a failed pack.
    std::fs::write(&out, b"previous").unwrap();
    let r = Command::new("sh").arg("-c").arg(&cmd).output().unwrap();
    assert!(!r.status.success());
    assert_eq!(std::fs::read(&out).unwrap(), b"previous");
    assert_eq!(listing(&d), vec!["small2d.fmu"]);
    // An output that is a directory: refused before any work, naming it.
    let dir_out = d.join("a_dir.fmu");
    std::fs::create_dir(&dir_out).unwrap();
    let e = pack_fmu(&small2d(), &common::built_library(), &dir_out).unwrap_err();
    assert!(
        e.contains(dir_out.to_str().unwrap()) && e.contains("is a directory"),
        "{e}"
    );
    assert_eq!(listing(&d), vec!["a_dir.fmu", "small2d.fmu"]);
    // A missing library and an output under a file.
    let e = pack_fmu(&small2d(), &d.join("none.so"), &d.join("x.fmu")).unwrap_err();
    assert!(
        e.contains("none.so") && e.contains("No such file or directory"),
        "{e}"
    );
    let e = pack_fmu(&small2d(), &common::built_library(), &out.join("x.fmu")).unwrap_err();
    assert!(
        e.contains("small2d.fmu/x.fmu") && e.contains("Not a directory (os error 20)"),
        "{e}"
    );
    // Success writes exactly the FMU.
    pack_fmu(&small2d(), &common::built_library(), &out).unwrap();
    assert_eq!(&std::fs::read(&out).unwrap()[..2], b"PK");
    assert_eq!(listing(&d), vec!["a_dir.fmu", "small2d.fmu"]);
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn the_output_is_never_the_scene() {
    let d = scratch("same");
    let scene = d.join("s.json");
    std::fs::copy(root().join("tests/data/small2d.json"), &scene).unwrap();
    let before = std::fs::read(&scene).unwrap();
    for out in [scene.clone(), d.join(".").join("s.json")] {
        let r = Command::new(env!("CARGO_BIN_EXE_mps"))
            .args(["pack", scene.to_str().unwrap(), "--lib"])
            .arg(common::built_library())
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap();
        let e = String::from_utf8_lossy(&r.stderr);
        assert!(
            !r.status.success() && e.contains("is the scene file itself"),
            "{e}"
        );
        assert_eq!(std::fs::read(&scene).unwrap(), before);
    }
    // Nor the library.
    let lib_copy = d.join("lib.so");
    std::fs::copy(common::built_library(), &lib_copy).unwrap();
    let e = pack_fmu(&small2d(), &lib_copy, &lib_copy).unwrap_err();
    assert!(e.contains("is the library itself"), "{e}");
    std::fs::remove_dir_all(&d).ok();
}

/// `mps pack small2d --lib <built> --out <out>`: its exit status and stderr.
fn pack_cli(out: &Path) -> (bool, String) {
    let r = Command::new(env!("CARGO_BIN_EXE_mps"))
        .arg("pack")
        .arg(root().join("tests/data/small2d.json"))
        .arg("--lib")
        .arg(common::built_library())
        .arg("--out")
        .arg(out)
        .output()
        .unwrap();
    (
        r.status.success(),
        String::from_utf8_lossy(&r.stderr).into_owned(),
    )
}

#[test]
fn write_xml_replaces_a_file_whole_and_follows_no_link() {
    // Issue 27 (left from its audit): `mps pack --xml-only --write-xml DIR` wrote
    // DIR/<scene>.xml with a plain write, which follows a link there (and truncates before
    // writing). It now writes as the FMU is written: a new file renamed over the old one.
    let d = scratch("xml");
    let xml = |dir: &Path| {
        let r = Command::new(env!("CARGO_BIN_EXE_mps"))
            .args(["pack", "--xml-only", "--write-xml"])
            .arg(dir)
            .arg(root().join("tests/data/small2d.json"))
            .output()
            .unwrap();
        (
            r.status.success(),
            String::from_utf8_lossy(&r.stderr).into_owned(),
        )
    };
    // An old file is replaced by the whole description.
    let f = d.join("small2d.xml");
    std::fs::write(&f, b"old").unwrap();
    let (ok, e) = xml(&d);
    assert!(ok, "{e}");
    let written = std::fs::read_to_string(&f).unwrap();
    assert!(
        written.starts_with("<?xml") && written.trim_end().ends_with("</fmiModelDescription>"),
        "{written}"
    );
    assert_eq!(listing(&d), ["small2d.xml"], "no temporary file is left");
    // A link there is refused and left alone, and so is the file it points to.
    let target = d.join("elsewhere.txt");
    std::fs::write(&target, b"keep me").unwrap();
    std::fs::remove_file(&f).unwrap();
    std::os::unix::fs::symlink(&target, &f).unwrap();
    let (ok, e) = xml(&d);
    assert!(!ok && e.contains("is a symbolic link"), "{e}");
    assert!(std::fs::symlink_metadata(&f)
        .unwrap()
        .file_type()
        .is_symlink());
    assert_eq!(std::fs::read(&target).unwrap(), b"keep me");
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn an_output_that_is_not_a_regular_file_is_refused_and_left_alone() {
    use std::os::unix::fs::FileTypeExt;
    let d = scratch("target");
    // A named pipe: refused (it was replaced by the zip before), still a pipe.
    let fifo = d.join("pipe.fmu");
    assert!(Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .unwrap()
        .success());
    let (ok, e) = pack_cli(&fifo);
    assert!(
        !ok && e.contains(fifo.to_str().unwrap()) && e.contains("named pipe (FIFO)"),
        "{e}"
    );
    assert!(std::fs::symlink_metadata(&fifo)
        .unwrap()
        .file_type()
        .is_fifo());
    // A symbolic link to a file: not followed and not replaced; the file keeps its bytes.
    let target = d.join("real.fmu");
    std::fs::write(&target, b"previous").unwrap();
    let link = d.join("link.fmu");
    std::os::unix::fs::symlink(&target, &link).unwrap();
    let (ok, e) = pack_cli(&link);
    assert!(
        !ok && e.contains("is a symbolic link") && e.contains(target.to_str().unwrap()),
        "{e}"
    );
    assert!(std::fs::symlink_metadata(&link)
        .unwrap()
        .file_type()
        .is_symlink());
    assert_eq!(std::fs::read(&target).unwrap(), b"previous");
    // A dangling link too (the FMU would appear wherever it points).
    let dangling = d.join("dangling.fmu");
    std::os::unix::fs::symlink(d.join("nowhere/x.fmu"), &dangling).unwrap();
    let (ok, e) = pack_cli(&dangling);
    assert!(!ok && e.contains("is a symbolic link"), "{e}");
    // A directory.
    let dir = d.join("dir.fmu");
    std::fs::create_dir(&dir).unwrap();
    let (ok, e) = pack_cli(&dir);
    assert!(!ok && e.contains("is a directory"), "{e}");
    // A character device: as root, a null device made in the scratch directory (never a device
    // of /dev, which an unfixed mps would replace); otherwise /dev/null, which a user cannot
    // replace anyway.
    let root_user = unsafe { libc::geteuid() } == 0;
    let device = if root_user {
        let dev = d.join("null.fmu");
        assert!(Command::new("mknod")
            .arg(&dev)
            .args(["c", "1", "3"])
            .status()
            .unwrap()
            .success());
        dev
    } else {
        PathBuf::from("/dev/null")
    };
    let (ok, e) = pack_cli(&device);
    assert!(!ok && e.contains("is a character device"), "{e}");
    assert!(std::fs::symlink_metadata(&device)
        .unwrap()
        .file_type()
        .is_char_device());
    // Nothing else was created (no temporary file left).
    let mut want = vec![
        "dangling.fmu",
        "dir.fmu",
        "link.fmu",
        "pipe.fmu",
        "real.fmu",
    ];
    if root_user {
        want.insert(3, "null.fmu");
    }
    assert_eq!(listing(&d), want);
    // A regular file is replaced.
    let (ok, e) = pack_cli(&target);
    assert!(ok, "{e}");
    assert_eq!(&std::fs::read(&target).unwrap()[..2], b"PK");
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn only_a_library_of_the_same_sources_is_packed() {
    use mps_solid::fmi::pack::{library_source_id, newest_glibc};
    use mps_solid::fmi::source_id::SOURCE_ID;
    let lib = std::fs::read(common::built_library()).unwrap();
    assert_eq!(library_source_id(&lib).as_deref(), Some(SOURCE_ID));
    assert!(SOURCE_ID.starts_with("mps-solid "), "{SOURCE_ID}");
    // The build's glibc is read from the version needs (what objdump -T lists).
    let (major, minor) = newest_glibc(&lib).unwrap();
    assert!(major == 2 && minor >= 2, "{major}.{minor}");
    // The same library with another source id (one digit changed) is refused.
    let at = lib
        .windows(SOURCE_ID.len())
        .position(|w| w == SOURCE_ID.as_bytes())
        .unwrap();
    let mut other = lib.clone();
    let last = at + SOURCE_ID.len() - 1;
    other[last] = if other[last] == b'0' { b'1' } else { b'0' };
    let d = scratch("source");
    let other_path = d.join("libother.so");
    std::fs::write(&other_path, &other).unwrap();
    assert_ne!(library_source_id(&other).as_deref(), Some(SOURCE_ID));
    let e = pack_fmu(&small2d(), &other_path, &d.join("x.fmu")).unwrap_err();
    assert!(
        e.contains("libother.so") && e.contains("built from other sources"),
        "{e}"
    );
    assert_eq!(listing(&d), vec!["libother.so"]);
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn pack_ships_the_portable_library_by_default() {
    // A copy of the program in a target directory of its own (hard links: same file system),
    // with a non-library where the release library would be, so that packing it would fail.
    let t = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("pack-default-{}", std::process::id()));
    std::fs::remove_dir_all(&t).ok();
    let release = t.join("target/release");
    std::fs::create_dir_all(&release).unwrap();
    let exe = release.join("mps");
    std::fs::hard_link(env!("CARGO_BIN_EXE_mps"), &exe)
        .or_else(|_| std::fs::copy(env!("CARGO_BIN_EXE_mps"), &exe).map(|_| ()))
        .unwrap();
    std::fs::write(release.join("libmps_solid.so"), b"not the library to ship").unwrap();
    let fmu = t.join("small2d.fmu");
    let pack = || {
        Command::new(&exe)
            .arg("pack")
            .arg(root().join("tests/data/small2d.json"))
            .arg("--out")
            .arg(&fmu)
            .output()
            .unwrap()
    };
    // Not built yet: an error that says how, and no FMU.
    let r = pack();
    let e = String::from_utf8_lossy(&r.stderr);
    let portable = t.join("target/x86_64-unknown-linux-gnu/fmu/libmps_solid.so");
    assert!(!r.status.success(), "{e}");
    assert!(
        e.contains(portable.to_str().unwrap()) && e.contains("scripts/build-fmu-lib.sh"),
        "{e}"
    );
    assert!(!fmu.exists());
    // Built (here: this build's library standing in for it): it is what the FMU carries.
    std::fs::create_dir_all(portable.parent().unwrap()).unwrap();
    std::fs::copy(common::built_library(), &portable).unwrap();
    let r = pack();
    let out = String::from_utf8_lossy(&r.stdout);
    assert!(
        r.status.success(),
        "{out}{}",
        String::from_utf8_lossy(&r.stderr)
    );
    assert!(
        out.contains(portable.to_str().unwrap()) && out.contains("needs glibc >= 2."),
        "{out}"
    );
    let mut z = zip::ZipArchive::new(std::fs::File::open(&fmu).unwrap()).unwrap();
    let mut shipped = Vec::new();
    std::io::Read::read_to_end(
        &mut z.by_name("binaries/linux64/small2d.so").unwrap(),
        &mut shipped,
    )
    .unwrap();
    assert!(shipped == std::fs::read(&portable).unwrap());
    std::fs::remove_dir_all(&t).ok();
}
