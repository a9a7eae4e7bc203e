//! VTK XML output for ParaView: one `.vtu` unstructured grid of vertex cells per snapshot
//! (written by `vtkio`), and a `.pvd` collection giving each file its time (written with
//! `quick-xml`).
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;

use quick_xml::Writer;
use vtkio::model::{
    Attribute, Attributes, ByteOrder, CellType, Cells, DataSet, UnstructuredGridPiece, Version,
    VertexNumbers, Vtk,
};

use crate::sim::ParticleSnapshot;

/// Checks that every per-particle array of `snap` has one entry per particle.
pub(crate) fn check_lengths(snap: &ParticleSnapshot) -> Result<usize, String> {
    let n = snap.position.len();
    let lens = [
        ("body", snap.body.len()),
        ("displacement", snap.displacement.len()),
        ("velocity", snap.velocity.len()),
        ("surface", snap.surface.len()),
        ("broken_bonds", snap.broken_bonds.len()),
    ];
    // `fixed` may be empty (no particle held; snapshots written before it existed), and so may
    // the volumes, normals and areas.
    let fixed = [
        ("fixed", snap.fixed.len()),
        ("volume", snap.volume.len()),
        ("normal", snap.normal.len()),
        ("area", snap.area.len()),
    ]
    .into_iter()
    .filter(|&(_, len)| len != 0);
    for (name, len) in lens.into_iter().chain(fixed) {
        if len != n {
            return Err(format!(
                "snapshot has {n} positions but {len} entries in `{name}`"
            ));
        }
    }
    Ok(n)
}

fn flat(v: &[[f64; 3]]) -> Vec<f64> {
    v.iter().flatten().copied().collect()
}

/// The snapshot as a `vtkio` model: an unstructured grid with one VTK_VERTEX cell per particle
/// and the point data arrays `body` (Int32, the active scalars), `displacement` (Float64 x 3,
/// the active vectors, m), `velocity` (Float64 x 3, m/s), `surface` (UInt8, 1 on the contact
/// surface), `broken_bonds` (Int32) and `fixed` (UInt8, 1 where a boundary holds the particle);
/// when known, `volume` (Float64, the volume the particle stands for, m^3), and of bodies filled
/// from shapes `normal` (Float64 x 3, the solid's outward normal at surface particles) and
/// `area` (Float64, the solid's surface area they carry, m^2).
pub fn snapshot_to_vtk(snap: &ParticleSnapshot) -> Result<Vtk, String> {
    let n = check_lengths(snap)?;
    let to_i32 = |v: &[u32], what: &str| -> Result<Vec<i32>, String> {
        v.iter()
            .map(|&x| i32::try_from(x).map_err(|_| format!("{what} {x} does not fit an Int32")))
            .collect()
    };
    let point = vec![
        Attribute::scalars("body", 1).with_data(to_i32(&snap.body, "body")?),
        Attribute::vectors("displacement").with_data(flat(&snap.displacement)),
        Attribute::generic("velocity", 3).with_data(flat(&snap.velocity)),
        Attribute::generic("surface", 1).with_data(
            snap.surface
                .iter()
                .map(|&s| u8::from(s))
                .collect::<Vec<u8>>(),
        ),
        Attribute::generic("broken_bonds", 1)
            .with_data(to_i32(&snap.broken_bonds, "broken bond count")?),
        Attribute::generic("fixed", 1).with_data(
            (0..n)
                .map(|i| u8::from(snap.fixed.get(i).copied().unwrap_or(false)))
                .collect::<Vec<u8>>(),
        ),
    ];
    let mut point = point;
    if !snap.volume.is_empty() {
        point.push(Attribute::generic("volume", 1).with_data(snap.volume.clone()));
    }
    if !snap.normal.is_empty() {
        point.push(Attribute::generic("normal", 3).with_data(flat(&snap.normal)));
    }
    if !snap.area.is_empty() {
        point.push(Attribute::generic("area", 1).with_data(snap.area.clone()));
    }
    let piece = UnstructuredGridPiece {
        points: flat(&snap.position).into(),
        cells: Cells {
            // XML layout: offsets are the end of each cell in `connectivity`, no leading zero.
            cell_verts: VertexNumbers::XML {
                connectivity: (0..n as u64).collect(),
                offsets: (1..=n as u64).collect(),
            },
            types: vec![CellType::Vertex; n],
        },
        data: Attributes {
            point,
            cell: Vec::new(),
        },
    };
    Ok(Vtk {
        version: Version::new_xml(1, 0),
        byte_order: ByteOrder::LittleEndian,
        title: format!("particles at t = {} s", snap.time),
        file_path: None,
        data: DataSet::inline(piece),
    })
}

/// Writes `snap` as a VTK XML UnstructuredGrid (`.vtu`, base64 binary, uncompressed) that
/// ParaView opens directly; see [`snapshot_to_vtk`] for the arrays.
pub fn write_vtu(path: &Path, snap: &ParticleSnapshot) -> Result<(), String> {
    let vtk = snapshot_to_vtk(snap)?;
    let file = File::create(path).map_err(|e| format!("creating {}: {e}", path.display()))?;
    let mut out = BufWriter::new(file);
    vtk.write_xml(&mut out)
        .map_err(|e| format!("writing {}: {e}", path.display()))?;
    out.flush()
        .map_err(|e| format!("writing {}: {e}", path.display()))
}

/// A ParaView collection (`.pvd`): a list of data files, each with its time, that ParaView
/// opens as one time series.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PvdWriter {
    entries: Vec<(f64, String)>,
}

impl PvdWriter {
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds a data set at `time` (s); `file` is written as given, so make it relative to the
    /// folder of the `.pvd` (ParaView resolves it from there).
    pub fn add(&mut self, time: f64, file: impl Into<String>) {
        self.entries.push((time, file.into()));
    }

    /// The data sets added so far, as (time, file).
    pub fn entries(&self) -> &[(f64, String)] {
        &self.entries
    }

    /// Writes the collection as XML to `out`.
    pub fn write_to(&self, out: impl Write) -> Result<(), String> {
        let mut w = Writer::new_with_indent(out, b' ', 2);
        let err = |e: std::io::Error| format!("writing pvd: {e}");
        w.write_event(quick_xml::events::Event::Decl(
            quick_xml::events::BytesDecl::new("1.0", None, None),
        ))
        .map_err(err)?;
        w.create_element("VTKFile")
            .with_attributes([
                ("type", "Collection"),
                ("version", "0.1"),
                ("byte_order", "LittleEndian"),
            ])
            .write_inner_content(|w| {
                w.create_element("Collection")
                    .write_inner_content(|w| {
                        for (time, file) in &self.entries {
                            // `{}` of an f64 is the shortest text that reads back exactly.
                            let t = format!("{time}");
                            w.create_element("DataSet")
                                .with_attributes([
                                    ("timestep", t.as_str()),
                                    ("group", ""),
                                    ("part", "0"),
                                    ("file", file.as_str()),
                                ])
                                .write_empty()?;
                        }
                        Ok(())
                    })
                    .map(|_| ())
            })
            .map_err(err)?;
        let mut out = w.into_inner();
        out.write_all(b"\n").map_err(err)?;
        out.flush().map_err(err)
    }

    /// Writes the collection to the file `path`.
    pub fn write(&self, path: &Path) -> Result<(), String> {
        let file = File::create(path).map_err(|e| format!("creating {}: {e}", path.display()))?;
        self.write_to(BufWriter::new(file))
            .map_err(|e| format!("{}: {e}", path.display()))
    }
}

/// Writes a body surface mesh (`mps run --surface`) as a `.vtu`: its triangles (lines in 2D)
/// at their reference positions, with point data `displacement` (Float64 x 3, m, the active
/// vectors: ParaView's "Warp By Vector" shows the deformed surface) and cell data `body`.
pub fn write_surface_vtu(
    path: &Path,
    mesh: &crate::scene::surface::SurfaceMesh,
    displacement: &[[f64; 3]],
    time: f64,
) -> Result<(), String> {
    let n = mesh.points.len();
    if displacement.len() != n || mesh.cell_body.len() != mesh.cells.len() {
        return Err(format!(
            "surface mesh has {n} points but {} displacements, {} cells but {} bodies",
            displacement.len(),
            mesh.cells.len(),
            mesh.cell_body.len()
        ));
    }
    let mut connectivity = Vec::new();
    let mut offsets = Vec::with_capacity(mesh.cells.len());
    let mut types = Vec::with_capacity(mesh.cells.len());
    for c in &mesh.cells {
        connectivity.extend(c.iter().map(|&i| i as u64));
        offsets.push(connectivity.len() as u64);
        types.push(if c.len() == 2 {
            CellType::Line
        } else {
            CellType::Triangle
        });
    }
    let body: Vec<i32> = mesh.cell_body.iter().map(|&b| b as i32).collect();
    let piece = UnstructuredGridPiece {
        points: flat(&mesh.points).into(),
        cells: Cells {
            cell_verts: VertexNumbers::XML {
                connectivity,
                offsets,
            },
            types,
        },
        data: Attributes {
            point: vec![Attribute::vectors("displacement").with_data(flat(displacement))],
            cell: vec![Attribute::scalars("body", 1).with_data(body)],
        },
    };
    let vtk = Vtk {
        version: Version::new_xml(1, 0),
        byte_order: ByteOrder::LittleEndian,
        title: format!("body surfaces at t = {time} s"),
        file_path: None,
        data: DataSet::inline(piece),
    };
    let file = File::create(path).map_err(|e| format!("creating {}: {e}", path.display()))?;
    let mut out = BufWriter::new(file);
    vtk.write_xml(&mut out)
        .map_err(|e| format!("writing {}: {e}", path.display()))?;
    out.flush()
        .map_err(|e| format!("writing {}: {e}", path.display()))
}
