//! Snapshot output: a short run of case 1 written as a series (.vtu + .pvd + .png) reads back
//! with the particle count, the exact displacement and the times, and the PNGs decode. The 3D
//! views (the paper's Figure 9): colours, projection, depth order, bad input, a short case 3
//! Figure 9.
use std::path::PathBuf;

use mps_solid::output::{
    broken_pairs, write_grid_png_3d, write_png_3d, write_series, write_vtu, Camera, Frame3d,
    Grid3d, Image3d, Label3d, PvdWriter, View,
};
use mps_solid::physics::ElasticModel;
use mps_solid::sim::ParticleSnapshot;
use mps_solid::studies::cases::case1_scene;
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
        volume: vec![],
        normal: vec![],
        area: vec![],
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

// ---------------------------------------------------------------------------------------------
// 3D views.

/// A tiny two-body scene as a snapshot: a "block" of 8 x 3 x 8 particles on z in [0, 0.35] and
/// a "cube" of 4 x 4 x 4 above it (z from 0.6), spacing 0.05 m, nothing broken.
fn two_bodies() -> ParticleSnapshot {
    let dp = 0.05;
    let mut body = Vec::new();
    let mut position = Vec::new();
    let mut lattice = |b: u32, n: [usize; 3], origin: [f64; 3]| {
        for i in 0..n[0] {
            for j in 0..n[1] {
                for k in 0..n[2] {
                    body.push(b);
                    position.push([
                        origin[0] + dp * i as f64,
                        origin[1] + dp * j as f64,
                        origin[2] + dp * k as f64,
                    ]);
                }
            }
        }
    };
    lattice(0, [4, 4, 4], [0.1, 0.05, 0.6]);
    lattice(1, [8, 3, 8], [0.0, -0.15, 0.0]);
    let n = position.len();
    ParticleSnapshot {
        time: 0.25,
        body,
        position,
        displacement: vec![[0.0; 3]; n],
        velocity: vec![[0.0; 3]; n],
        surface: vec![true; n],
        broken_bonds: vec![0; n],
        fixed: vec![false; n],
        volume: vec![],
        normal: vec![],
        area: vec![],
    }
}

fn names() -> Vec<String> {
    vec!["cube".into(), "block".into()]
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Kind {
    Salmon,
    Blue,
    Red,
    Other,
}

/// What a reader sees in a pixel: the cube's salmon, the block's blue or the broken-bond red,
/// at any shade (shading scales the colour, so the ratios stay).
fn classify(p: [u8; 3]) -> Kind {
    let [r, g, b] = p.map(f64::from);
    if r > 60.0 && g < 0.25 * r && b < 0.25 * r {
        Kind::Red
    } else if r > 60.0 && (0.38..0.64).contains(&(g / r)) && (0.33..0.6).contains(&(b / r)) {
        Kind::Salmon
    } else if b > r + 40.0 && b > g + 20.0 {
        Kind::Blue
    } else {
        Kind::Other
    }
}

/// The image decoded, checked against the size reported.
fn decode(path: &std::path::Path, img: &Image3d) -> image::RgbImage {
    let bytes = std::fs::read(path).unwrap();
    assert_eq!(png_size(&bytes), img.size, "IHDR size = reported size");
    let im = image::load_from_memory_with_format(&bytes, image::ImageFormat::Png)
        .expect("PNG decodes")
        .to_rgb8();
    assert_eq!(im.dimensions(), img.size);
    im
}

/// Pixels of each kind inside a rectangle (left, top, right, bottom), and their mean row.
fn census(im: &image::RgbImage, rect: [i32; 4]) -> Vec<(Kind, usize, f64)> {
    let mut out = Vec::new();
    for kind in [Kind::Salmon, Kind::Blue, Kind::Red] {
        let (mut n, mut rows) = (0usize, 0.0);
        for y in rect[1].max(0)..rect[3].min(im.height() as i32) {
            for x in rect[0].max(0)..rect[2].min(im.width() as i32) {
                if classify(im.get_pixel(x as u32, y as u32).0) == kind {
                    n += 1;
                    rows += y as f64;
                }
            }
        }
        out.push((kind, n, if n > 0 { rows / n as f64 } else { f64::NAN }));
    }
    out
}

fn count(c: &[(Kind, usize, f64)], k: Kind) -> usize {
    c.iter().find(|e| e.0 == k).unwrap().1
}
fn mean_row(c: &[(Kind, usize, f64)], k: Kind) -> f64 {
    c.iter().find(|e| e.0 == k).unwrap().2
}

#[test]
fn view3d_colours_projection_and_broken_bonds() {
    let dir = TempDir::new("view3d");
    let snap = two_bodies();
    let label = Label3d {
        body_names: names(),
        variant: "test variant".into(),
        note: Some("a note".into()),
    };
    let frame = Frame3d::fit(Camera::default(), &[&snap]).unwrap();

    // Nothing broken: both body colours in the plot, no red anywhere (the legend lists no
    // broken class either).
    let path = dir.0.join("intact.png");
    let img = write_png_3d(&path, &snap, &label, &frame).expect("3D view");
    let im = decode(&path, &img);
    assert!(img.size.0 >= 500 && img.size.1 >= 300, "{:?}", img.size);
    let g = img.panels[0];
    assert!(g.plot[0] >= 0 && g.plot[2] <= img.size.0 as i32 && g.plot[3] <= img.size.1 as i32);
    let plot = [
        g.plot[0] - g.radius,
        g.plot[1] - g.radius,
        g.plot[2] + g.radius,
        g.plot[3] + g.radius,
    ];
    let c = census(&im, plot);
    let whole = census(&im, [0, 0, img.size.0 as i32, img.size.1 as i32]);
    assert!(count(&c, Kind::Salmon) > 300, "cube pixels: {c:?}");
    assert!(count(&c, Kind::Blue) > 1000, "block pixels: {c:?}");
    assert_eq!(
        count(&whole, Kind::Red),
        0,
        "no broken bond, no red: {whole:?}"
    );
    // The cube (z >= 0.6) is above the block (z <= 0.35) in the image.
    assert!(
        mean_row(&c, Kind::Salmon) < mean_row(&c, Kind::Blue),
        "cube rows {} block rows {}",
        mean_row(&c, Kind::Salmon),
        mean_row(&c, Kind::Blue)
    );
    // The pixel mapping: larger z is higher (smaller row), the same x and y.
    let (_, y_low) = g.pixel([0.1, 0.0, 0.0]);
    let (_, y_high) = g.pixel([0.1, 0.0, 0.3]);
    assert!(y_high < y_low, "{y_high} !< {y_low}");
    // The particle nearest the camera is drawn last: its centre pixel has its body's colour.
    let b = Camera::default().basis();
    let depth = |p: &[f64; 3]| p[0] * b[2][0] + p[1] * b[2][1] + p[2] * b[2][2];
    let nearest = (0..snap.position.len())
        .max_by(|&i, &j| depth(&snap.position[i]).total_cmp(&depth(&snap.position[j])))
        .unwrap();
    let (px, py) = g.pixel(snap.position[nearest]);
    let want = if snap.body[nearest] == 0 {
        Kind::Salmon
    } else {
        Kind::Blue
    };
    assert_eq!(classify(im.get_pixel(px as u32, py as u32).0), want);

    // Broken bonds: red in the plot, darker with more lost bonds, and the count in the title.
    let mut broken = snap.clone();
    broken.broken_bonds[nearest] = 12;
    let block: Vec<usize> = (0..broken.body.len())
        .filter(|&i| broken.body[i] == 1)
        .collect();
    for &i in &block[..20] {
        broken.broken_bonds[i] = 1;
    }
    assert_eq!(broken_pairs(&broken), (12 + 20) / 2);
    let path = dir.0.join("broken.png");
    let img = write_png_3d(&path, &broken, &label, &frame).unwrap();
    let im = decode(&path, &img);
    let g = img.panels[0];
    let c = census(&im, [g.plot[0], g.plot[1], g.plot[2], g.plot[3]]);
    assert!(count(&c, Kind::Red) > 20, "{c:?}");
    let (px, py) = g.pixel(broken.position[nearest]);
    let centre = im.get_pixel(px as u32, py as u32).0;
    assert_eq!(classify(centre), Kind::Red);
    let first = block[0];
    assert!(
        depth(&broken.position[first]) < depth(&broken.position[nearest]),
        "the one-bond particle is not the nearest"
    );
    // The 12-bond particle is the darkest class, darker than the one-bond class.
    assert!(centre[0] < 120, "12 lost bonds drawn as {centre:?}");
    // The one-bond particles on the near edge show the lightest class, exactly.
    let one = mps_solid::output::png::BROKEN_CLASSES[0].1;
    let light = im.pixels().filter(|p| p.0 == [one.0, one.1, one.2]).count();
    assert!(light > 20, "{light} pixels of the one-bond red");

    // A particle thrown far away: the bulk frame leaves it out (same frame as without it) and
    // the picture is still drawn; the plain frame would shrink the bodies to a few pixels.
    let mut thrown = broken.clone();
    thrown.position[0] = [0.0, 0.0, 20.0];
    let bulk = Frame3d::fit_bulk(Camera::default(), &[&thrown]).unwrap();
    let plain = Frame3d::fit(Camera::default(), &[&thrown]).unwrap();
    assert!(bulk.skip_outside && !plain.skip_outside);
    assert!(plain.up[1] > 15.0, "{:?}", plain.up);
    for k in 0..2 {
        assert!(
            (bulk.right[k] - frame.right[k]).abs() < 0.06,
            "{bulk:?} {frame:?}"
        );
        assert!(
            (bulk.up[k] - frame.up[k]).abs() < 0.06,
            "{bulk:?} {frame:?}"
        );
    }
    let img = write_png_3d(&dir.0.join("thrown.png"), &thrown, &label, &bulk).unwrap();
    assert!((img.panels[0].scale - g.scale).abs() < 0.1 * g.scale);
    assert!(write_png_3d(&dir.0.join("x.png"), &thrown, &label, &frame).is_err());

    // Two single particles at the same x, y: the higher one is drawn higher.
    let mut pair = two_bodies();
    pair.position.truncate(2);
    pair.body = vec![0, 1];
    pair.position = vec![[0.0, 0.0, 1.0], [0.0, 0.0, 0.0]];
    for v in [&mut pair.displacement, &mut pair.velocity] {
        v.truncate(2);
    }
    pair.surface.truncate(2);
    pair.broken_bonds.truncate(2);
    pair.fixed.truncate(2);
    let f2 = Frame3d::fit(Camera::default(), &[&pair]).unwrap();
    let path = dir.0.join("pair.png");
    let img = write_png_3d(&path, &pair, &label, &f2).unwrap();
    let im = decode(&path, &img);
    let g = img.panels[0];
    let (xa, ya) = g.pixel([0.0, 0.0, 1.0]);
    let (xb, yb) = g.pixel([0.0, 0.0, 0.0]);
    assert!(ya < yb);
    assert_eq!(classify(im.get_pixel(xa as u32, ya as u32).0), Kind::Salmon);
    assert_eq!(classify(im.get_pixel(xb as u32, yb as u32).0), Kind::Blue);
}

#[test]
fn view3d_grid_and_a_real_snapshot() {
    let dir = TempDir::new("grid3d");
    // A real 3D scene: the small cantilever (one body named "beam", palette colour; its clamp
    // held), nothing broken.
    let scene = mps_solid::Scene::load(std::path::Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/data/small3d.json"
    )))
    .unwrap();
    let mut sim = Simulation::new(&scene).unwrap();
    sim.advance_to(0.02).unwrap();
    let snap = sim.particle_snapshot();
    assert_eq!(broken_pairs(&snap), sim.broken_bonds());
    assert!(snap.fixed.iter().any(|&f| f));
    let frame = Frame3d::fit(Camera::default(), &[&snap]).unwrap();
    let label = Label3d {
        body_names: sim.body_names(),
        ..Label3d::default()
    };
    let path = dir.0.join("beam.png");
    let img = write_png_3d(&path, &snap, &label, &frame).unwrap();
    let im = decode(&path, &img);
    let c = census(&im, [0, 0, img.size.0 as i32, img.size.1 as i32]);
    assert_eq!(count(&c, Kind::Red), 0, "{c:?}");
    assert_eq!(count(&c, Kind::Salmon), 0, "no cube: {c:?}");

    // A grid of 2 rows x 2 columns, one frame: the panels are the same size, side by side.
    let a = two_bodies();
    let mut b = two_bodies();
    b.time = 0.5;
    b.broken_bonds[3] = 2;
    b.broken_bonds[7] = 2;
    let frame = Frame3d::fit(Camera::default(), &[&a, &b]).unwrap();
    let cell = |s: &ParticleSnapshot| {
        (
            s.clone(),
            Label3d {
                body_names: names(),
                ..Label3d::default()
            },
        )
    };
    let (ca, cb) = (cell(&a), cell(&b));
    let grid = Grid3d {
        title: "a grid".into(),
        subtitle: "line one\nline two".into(),
        columns: vec!["left".into(), "right".into()],
        cells: vec![
            vec![(&ca.0, ca.1.clone()), (&cb.0, cb.1.clone())],
            vec![(&cb.0, cb.1.clone()), (&ca.0, ca.1.clone())],
        ],
    };
    let path = dir.0.join("grid.png");
    let img = write_grid_png_3d(&path, &grid, &frame).unwrap();
    let im = decode(&path, &img);
    assert_eq!(img.panels.len(), 4);
    let p = &img.panels;
    let w = |g: &mps_solid::output::PanelGeometry| (g.plot[2] - g.plot[0], g.plot[3] - g.plot[1]);
    assert!(p.iter().all(|g| w(g) == w(&p[0])));
    assert_eq!(p[0].plot[1], p[1].plot[1], "one row");
    assert!(p[1].plot[0] > p[0].plot[2], "columns side by side");
    assert!(p[2].plot[1] > p[0].plot[3], "rows one under the other");
    // Red only in the panels of b (top right, bottom left).
    let red = |g: &mps_solid::output::PanelGeometry| count(&census(&im, g.plot), Kind::Red);
    assert_eq!(
        (
            red(&p[0]) > 0,
            red(&p[1]) > 0,
            red(&p[2]) > 0,
            red(&p[3]) > 0
        ),
        (false, true, true, false)
    );
}

#[test]
fn view3d_bad_input_is_an_error() {
    let dir = TempDir::new("view3d_bad");
    let good = two_bodies();
    let frame = Frame3d::fit(Camera::default(), &[&good]).unwrap();
    let label = Label3d::default();
    let ok_path = dir.0.join("ok.png");

    let mut empty = good.clone();
    for v in [
        &mut empty.position,
        &mut empty.displacement,
        &mut empty.velocity,
    ] {
        v.clear();
    }
    empty.body.clear();
    empty.surface.clear();
    empty.broken_bonds.clear();
    empty.fixed.clear();
    let e = Frame3d::fit(Camera::default(), &[&empty]).unwrap_err();
    assert!(e.contains("no particles"), "{e}");
    assert!(write_png_3d(&ok_path, &empty, &label, &frame).is_err());
    assert!(Frame3d::fit(Camera::default(), &[]).is_err());

    for bad in [f64::NAN, f64::INFINITY] {
        let mut s = good.clone();
        s.position[5][2] = bad;
        let e = Frame3d::fit(Camera::default(), &[&s]).unwrap_err();
        assert!(e.contains("particle 5") && e.contains("non-finite"), "{e}");
        assert!(write_png_3d(&ok_path, &s, &label, &frame).is_err());
    }
    let mut s = good.clone();
    s.time = f64::NAN;
    assert!(write_png_3d(&ok_path, &s, &label, &frame).is_err());

    // Mismatched arrays, a particle outside the frame, a bad camera.
    let mut s = good.clone();
    s.broken_bonds.pop();
    assert!(write_png_3d(&ok_path, &s, &label, &frame).is_err());
    let mut s = good.clone();
    s.position[0] = [10.0, 0.0, 0.0];
    let e = write_png_3d(&ok_path, &s, &label, &frame).unwrap_err();
    assert!(e.contains("outside the frame"), "{e}");
    for cam in [
        Camera {
            azimuth_deg: 0.0,
            elevation_deg: 90.0,
        },
        Camera {
            azimuth_deg: f64::NAN,
            elevation_deg: 10.0,
        },
    ] {
        assert!(Frame3d::fit(cam, &[&good]).is_err());
    }
    let e =
        Frame3d::fit_clipped(Camera::default(), &[&good], Some(([5.0; 3], [6.0; 3]))).unwrap_err();
    assert!(e.contains("no particle inside"), "{e}");

    // Unwritable paths: a missing directory, a directory itself.
    let missing = dir.0.join("no/such/dir/x.png");
    let e = write_png_3d(&missing, &good, &label, &frame).unwrap_err();
    assert!(e.contains("x.png"), "{e}");
    assert!(write_png_3d(&dir.0, &good, &label, &frame).is_err());

    // Grids: empty, ragged.
    let cells = vec![vec![(&good, label.clone())], vec![]];
    let grid = Grid3d {
        title: String::new(),
        subtitle: String::new(),
        columns: vec!["one".into()],
        cells,
    };
    assert!(write_grid_png_3d(&ok_path, &grid, &frame)
        .unwrap_err()
        .contains("row 1"));
    let grid = Grid3d {
        cells: vec![],
        ..grid
    };
    assert!(write_grid_png_3d(&ok_path, &grid, &frame).is_err());
    assert!(!ok_path.exists(), "nothing written on errors");
}

#[test]
#[ignore = "slow (35 s on a loaded 2-core machine): the full test command runs it"]
fn figure9_of_a_short_case3_run() {
    use mps_solid::studies::case3::{
        case3_report_with, case3_scene, figure9_foot, write_figure9, Figure9Capture, Figure9Column,
    };
    // Instants must be finite, >= 0 and increasing.
    assert!(Figure9Capture::new(&[]).is_err());
    assert!(Figure9Capture::new(&[0.1, 0.1]).is_err());
    assert!(Figure9Capture::new(&[f64::NAN]).is_err());
    assert!(Figure9Capture::new(&[-0.1]).is_err());

    let dir = TempDir::new("figure9");
    let mut columns = Vec::new();
    let mut names = Vec::new();
    for fc in [false, true] {
        let scene = case3_scene(0.05, fc, mps_solid::physics::ElasticModel::Corrected);
        let mut cap = Figure9Capture::new(&[0.0, 0.07]).unwrap();
        let r = case3_report_with(&scene, 0.07, 0.01, 0.0025, |sim, kind| cap.check(sim, kind))
            .unwrap();
        names = cap.body_names().to_vec();
        let panels = cap.finish(&r).unwrap();
        assert_eq!(panels.len(), 2);
        assert_eq!(panels[0].snapshot.time, 0.0, "the initial state");
        assert!((panels[1].snapshot.time - 0.07).abs() < 1e-9);
        assert!(!panels[1].stopped);
        columns.push(Figure9Column {
            heading: format!("fractured-surface contact {fc}"),
            tag: if fc { "with" } else { "without" }.into(),
            panels,
            failure: None,
        });
    }
    assert_eq!(names, ["cube", "block"]);
    // An instant after the end of the run is an error, not a panel.
    let scene = case3_scene(0.05, true, mps_solid::physics::ElasticModel::Corrected);
    let mut cap = Figure9Capture::new(&[0.0, 1.0]).unwrap();
    let r = case3_report_with(&scene, 0.005, 0.005, 0.0025, |s, k| cap.check(s, k)).unwrap();
    assert!(cap
        .finish(&r)
        .unwrap_err()
        .contains("before the Figure 9 instant 1"));

    let files = write_figure9(
        &dir.0,
        "fig",
        "title",
        "subtitle",
        &names,
        &columns,
        Camera::default(),
        Some(&figure9_foot()),
    )
    .unwrap();
    let expect: Vec<String> = [
        "fig.png",
        "fig_foot.png",
        "fig_without_t0.00.png",
        "fig_without_t0.07.png",
        "fig_with_t0.00.png",
        "fig_with_t0.07.png",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    let got: Vec<String> = files
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(got, expect);
    for f in &files {
        let bytes = std::fs::read(f).unwrap();
        let (w, h) = png_size(&bytes);
        let im = image::load_from_memory(&bytes).unwrap().to_rgb8();
        assert_eq!(im.dimensions(), (w, h));
        let c = census(&im, [0, 0, w as i32, h as i32]);
        assert_eq!(count(&c, Kind::Red), 0, "{f:?}: nothing broken by 0.07 s");
        assert!(count(&c, Kind::Blue) > 1000, "{f:?}: {c:?}");
        assert!(bytes.len() < 1_500_000, "{f:?}: {} bytes", bytes.len());
    }
    // The composite: two columns, a row per instant, wider than one panel image.
    let (cw, ch) = png_size(&std::fs::read(&files[0]).unwrap());
    let (pw, _) = png_size(&std::fs::read(&files[2]).unwrap());
    assert!(cw > pw && ch > 800, "{cw} x {ch}");
    // A directory that cannot be created is an error.
    let blocker = dir.0.join("file");
    std::fs::write(&blocker, b"x").unwrap();
    let e = write_figure9(
        &blocker.join("sub"),
        "fig",
        "t",
        "",
        &names,
        &columns,
        Camera::default(),
        None,
    )
    .unwrap_err();
    assert!(e.contains("creating"), "{e}");
}
