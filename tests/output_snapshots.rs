//! Snapshot output: a short run of case 1 written as a series (.vtu + .pvd + .png) reads back
//! with the particle count, the exact displacement and the times, and the PNGs decode.
use std::path::PathBuf;

use mps_solid::cases::case1_scene;
use mps_solid::output::{write_series, write_vtu, PvdWriter, View};
use mps_solid::physics::ElasticModel;
use mps_solid::sim::ParticleSnapshot;
use mps_solid::Simulation;
use quick_xml::events::Event;
use quick_xml::Reader;
use vtkio::model::{Attribute, CellType, DataSet, IOBuffer, Piece, VertexNumbers};
use vtkio::Vtk;

/// A fresh folder under the system temp dir, removed on drop.
struct TempDir(PathBuf);
impl TempDir {
    fn new(tag: &str) -> Self {
        let nanos = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap()
            .as_nanos();
        let p =
            std::env::temp_dir().join(format!("mps_output_{tag}_{}_{nanos}", std::process::id()));
        std::fs::create_dir_all(&p).unwrap();
        TempDir(p)
    }
}
impl Drop for TempDir {
    fn drop(&mut self) {
        if std::env::var_os("MPS_KEEP_OUTPUT").is_none() {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
}

fn snapshots() -> Vec<ParticleSnapshot> {
    let scene = case1_scene(0.05, ElasticModel::Corrected, None);
    let mut sim = Simulation::new(&scene).expect("scene");
    let mut snaps = vec![sim.particle_snapshot()];
    for k in 1..=2 {
        sim.advance_to(0.01 * k as f64).expect("advance");
        snaps.push(sim.particle_snapshot());
    }
    snaps
}

fn point_array<'a>(attrs: &'a [Attribute], name: &str) -> &'a IOBuffer {
    attrs
        .iter()
        .find_map(|a| match a {
            Attribute::DataArray(d) if d.name == name => Some(&d.data),
            _ => None,
        })
        .unwrap_or_else(|| panic!("no point array {name}"))
}

/// Width and height from a PNG's IHDR chunk, after checking the signature.
fn png_size(bytes: &[u8]) -> (u32, u32) {
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "PNG signature");
    assert_eq!(&bytes[12..16], b"IHDR");
    let be = |o: usize| u32::from_be_bytes(bytes[o..o + 4].try_into().unwrap());
    (be(16), be(20))
}

#[test]
fn series_reads_back() {
    let snaps = snapshots();
    let n = snaps[0].position.len();
    assert!(n > 100, "case 1 at dp 0.05 has {n} particles");
    assert!(snaps.last().unwrap().time > 0.0);
    let last_disp = &snaps.last().unwrap().displacement;
    assert!(
        last_disp.iter().any(|d| d[2] != 0.0),
        "the column has started to move"
    );

    let dir = TempDir::new("series");
    let written = write_series(&dir.0, "col", &snaps, Some(View::XZ)).expect("write series");
    assert_eq!(written.len(), 2 * snaps.len() + 1);
    assert!(written.iter().all(|p| p.is_file()));

    // .vtu: particle count, vertex cells, arrays equal to the snapshot.
    for (i, snap) in snaps.iter().enumerate() {
        let path = dir.0.join(format!("col_{i:04}.vtu"));
        let vtk = Vtk::import(&path).expect("vtkio reads the .vtu");
        let DataSet::UnstructuredGrid { pieces, .. } = vtk.data else {
            panic!("not an unstructured grid")
        };
        assert_eq!(pieces.len(), 1);
        let Piece::Inline(piece) = &pieces[0] else {
            panic!("piece not inline")
        };
        assert_eq!(piece.num_points(), n);
        let pos: Vec<f64> = snap.position.iter().flatten().copied().collect();
        assert_eq!(piece.points, IOBuffer::F64(pos));
        assert_eq!(piece.cells.types, vec![CellType::Vertex; n]);
        match &piece.cells.cell_verts {
            VertexNumbers::XML {
                connectivity,
                offsets,
            } => {
                assert_eq!(connectivity.len(), n);
                assert_eq!(offsets.last().copied(), Some(n as u64));
            }
            other => panic!("unexpected cell layout {other:?}"),
        }
        let pd = &piece.data.point;
        let disp: Vec<f64> = snap.displacement.iter().flatten().copied().collect();
        assert_eq!(point_array(pd, "displacement"), &IOBuffer::F64(disp));
        let vel: Vec<f64> = snap.velocity.iter().flatten().copied().collect();
        assert_eq!(point_array(pd, "velocity"), &IOBuffer::F64(vel));
        let body: Vec<i32> = snap.body.iter().map(|&b| b as i32).collect();
        assert_eq!(point_array(pd, "body"), &IOBuffer::I32(body));
        let surf: Vec<u8> = snap.surface.iter().map(|&s| s as u8).collect();
        assert_eq!(point_array(pd, "surface"), &IOBuffer::U8(surf));
        let broken: Vec<i32> = snap.broken_bonds.iter().map(|&b| b as i32).collect();
        assert_eq!(point_array(pd, "broken_bonds"), &IOBuffer::I32(broken));
        let fixed: Vec<u8> = snap.fixed.iter().map(|&f| f as u8).collect();
        assert!(fixed.contains(&1), "case 1's clamp holds particles");
        assert_eq!(point_array(pd, "fixed"), &IOBuffer::U8(fixed));
    }

    // .pvd: one DataSet per snapshot, times and files in order.
    let pvd = std::fs::read_to_string(dir.0.join("col.pvd")).unwrap();
    let mut reader = Reader::from_str(&pvd);
    let mut found = Vec::new();
    let mut root_type = None;
    loop {
        match reader.read_event().expect("well-formed pvd") {
            Event::Eof => break,
            Event::Start(e) | Event::Empty(e) => {
                let attr = |k: &str| {
                    e.try_get_attribute(k)
                        .unwrap()
                        .map(|a| a.unescape_value().unwrap().into_owned())
                };
                match e.name().as_ref() {
                    b"VTKFile" => root_type = attr("type"),
                    b"DataSet" => {
                        let t: f64 = attr("timestep").unwrap().parse().unwrap();
                        found.push((t, attr("file").unwrap()));
                    }
                    _ => {}
                }
            }
            _ => {}
        }
    }
    assert_eq!(root_type.as_deref(), Some("Collection"));
    assert_eq!(found.len(), snaps.len());
    for (i, (t, file)) in found.iter().enumerate() {
        assert_eq!(*t, snaps[i].time, "timestep reads back exactly");
        assert_eq!(file, &format!("col_{i:04}.vtu"));
    }

    // .png: decodes, size as in the header, not blank.
    for i in 0..snaps.len() {
        let path = dir.0.join(format!("col_{i:04}.png"));
        let bytes = std::fs::read(&path).unwrap();
        let (w, h) = png_size(&bytes);
        assert!(w >= 400 && h >= 300, "{w} x {h}");
        let img = image::load_from_memory_with_format(&bytes, image::ImageFormat::Png)
            .expect("PNG decodes")
            .to_rgb8();
        assert_eq!(img.dimensions(), (w, h));
        let coloured = img.pixels().filter(|p| p.0 != [255, 255, 255]).count();
        assert!(coloured > 1000, "only {coloured} non-white pixels");
    }
}

#[test]
fn every_view_and_edge_cases() {
    let dir = TempDir::new("views");
    let snap = snapshots().pop().unwrap();
    for (view, name) in [(View::XY, "xy"), (View::XZ, "xz"), (View::YZ, "yz")] {
        let p = dir.0.join(format!("v_{name}.png"));
        mps_solid::output::write_png(&p, &snap, view).expect("png");
        let (w, h) = png_size(&std::fs::read(&p).unwrap());
        assert!(w > 0 && h > 0);
        assert_eq!(name.parse::<View>().unwrap(), view);
    }

    // A snapshot with a broken-bond particle and a second body still plots and writes.
    let mut s = snap.clone();
    s.broken_bonds[0] = 3;
    s.body[1] = 1;
    mps_solid::output::write_png(&dir.0.join("marked.png"), &s, View::XZ).unwrap();
    write_vtu(&dir.0.join("marked.vtu"), &s).unwrap();

    // Empty snapshot: valid files, no panic.
    let empty = ParticleSnapshot {
        time: 0.0,
        body: vec![],
        position: vec![],
        displacement: vec![],
        velocity: vec![],
        surface: vec![],
        broken_bonds: vec![],
        fixed: vec![],
    };
    write_vtu(&dir.0.join("empty.vtu"), &empty).unwrap();
    mps_solid::output::write_png(&dir.0.join("empty.png"), &empty, View::XY).unwrap();

    // Mismatched lengths are an error, not a panic.
    let mut bad = snap.clone();
    bad.velocity.pop();
    assert!(write_vtu(&dir.0.join("bad.vtu"), &bad).is_err());

    // PvdWriter on its own.
    let mut pvd = PvdWriter::new();
    pvd.add(0.5, "a.vtu");
    pvd.add(1e-7, "b & c.vtu");
    let mut out = Vec::new();
    pvd.write_to(&mut out).unwrap();
    let text = String::from_utf8(out).unwrap();
    assert!(text.contains(r#"<VTKFile type="Collection""#), "{text}");
    assert!(text.contains("b &amp; c.vtu"), "{text}");
    assert_eq!(pvd.entries().len(), 2);
}
