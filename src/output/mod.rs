//! Particle snapshots to files: VTK XML `.vtu` (plus a `.pvd` time collection) for ParaView, PNG
//! scatter plots of a projection, and PNG 3D views (alone or in a grid, for the paper's
//! Figure 9: `case3::write_figure9`).
//!
//! [`write_series`] writes a whole run: `NAME_NNNN.vtu` per snapshot, `NAME.pvd` listing them
//! with their times, and `NAME_NNNN.png` when a [`View`] is given.
pub mod png;
pub mod vtk;

use std::path::{Path, PathBuf};

use crate::sim::ParticleSnapshot;

pub use self::png::{
    broken_pairs, write_grid_png_3d, write_png, write_png_3d, Camera, Frame3d, Grid3d, Image3d,
    Label3d, PanelGeometry, View, MAX_IMAGE_PIXELS,
};
pub use self::vtk::{write_surface_vtu, write_vtu, PvdWriter};

/// Writes `dir/name_NNNN.vtu` for each snapshot (NNNN = its index, zero padded to 4 digits),
/// `dir/name.pvd` listing them with their times, and `dir/name_NNNN.png` projected on
/// `png_view` when given. Creates `dir` if missing. Returns every path written: per snapshot the
/// `.vtu` then the `.png` (if any), the `.pvd` last.
pub fn write_series(
    dir: &Path,
    name: &str,
    snaps: &[ParticleSnapshot],
    png_view: Option<View>,
) -> Result<Vec<PathBuf>, String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("creating {}: {e}", dir.display()))?;
    let mut written = Vec::with_capacity(snaps.len() * 2 + 1);
    let mut pvd = PvdWriter::new();
    for (i, snap) in snaps.iter().enumerate() {
        let stem = format!("{name}_{i:04}");
        let vtu_name = format!("{stem}.vtu");
        let vtu = dir.join(&vtu_name);
        write_vtu(&vtu, snap)?;
        written.push(vtu);
        // Relative to the .pvd, which sits in the same folder: the series can be moved whole.
        pvd.add(snap.time, vtu_name);
        if let Some(view) = png_view {
            let png = dir.join(format!("{stem}.png"));
            write_png(&png, snap, view)?;
            written.push(png);
        }
    }
    let pvd_path = dir.join(format!("{name}.pvd"));
    pvd.write(&pvd_path)?;
    written.push(pvd_path);
    Ok(written)
}
