//! The output files of `mps run`, replaced only by a complete run: probes.csv, summary.json and
//! (with --energy) energy.csv are written as new temporary files in the output directory,
//! opened before the run so that an unusable directory fails first, and renamed onto their
//! names when the run has completed. A run that stopped early (blow-up, overlap) writes what it
//! computed as probes.partial.csv, summary.partial.json and energy.partial.csv and leaves the
//! complete results of an earlier run as they were; a complete run removes such partial files
//! (they belong to a run that its results replace). Anything that fails before the rename
//! removes the temporary files and changes nothing else.
use std::fs::File;
use std::io::Write;
use std::path::{Path, PathBuf};

/// The result files and their temporary files, open for writing.
pub struct RunOutputs {
    dir: PathBuf,
    /// (final name, temporary path, open file): probes, summary, energy (optional).
    files: Vec<(&'static str, PathBuf, Option<File>)>,
    energy: bool,
}

/// Where the results went.
pub struct Written {
    pub probes: PathBuf,
    pub summary: PathBuf,
    pub energy: Option<PathBuf>,
}

/// Names of a complete run's files and of a stopped run's: (probes, summary, energy).
const COMPLETE: [&str; 3] = ["probes.csv", "summary.json", "energy.csv"];
const PARTIAL: [&str; 3] = [
    "probes.partial.csv",
    "summary.partial.json",
    "energy.partial.csv",
];

impl RunOutputs {
    /// Creates `dir` and the temporary files in it (refused if anything exists at their names).
    pub fn open(dir: &Path, energy: bool) -> Result<RunOutputs, String> {
        std::fs::create_dir_all(dir)
            .map_err(|e| format!("cannot create the directory {}: {e}", dir.display()))?;
        let mut outputs = RunOutputs {
            dir: dir.to_path_buf(),
            files: Vec::new(),
            energy,
        };
        let n = if energy { 3 } else { 2 };
        for name in &COMPLETE[..n] {
            let tmp = dir.join(format!(".{name}.{}.tmp", std::process::id()));
            let file = std::fs::OpenOptions::new()
                .write(true)
                .create_new(true)
                .open(&tmp)
                .map_err(|e| {
                    format!("cannot write in {}: {}: {e}", dir.display(), tmp.display())
                })?;
            outputs.files.push((name, tmp, Some(file)));
        }
        Ok(outputs)
    }

    /// Writes the texts into the temporary files and renames them onto the complete names
    /// (`complete`) or the partial ones. Returns the final paths.
    pub fn commit(
        &mut self,
        probes: &str,
        summary: &str,
        energy: Option<&str>,
        complete: bool,
    ) -> Result<Written, String> {
        let names = if complete { COMPLETE } else { PARTIAL };
        let texts = [Some(probes), Some(summary), energy];
        for (k, (_, tmp, file)) in self.files.iter_mut().enumerate() {
            let text = texts[k].unwrap_or_default();
            let mut f = file.take().expect("written once");
            f.write_all(text.as_bytes())
                .and_then(|()| f.sync_all())
                .map_err(|e| format!("cannot write {}: {e}", tmp.display()))?;
        }
        let target = |k: usize| self.dir.join(names[k]);
        for (k, (_, tmp, _)) in self.files.iter().enumerate() {
            std::fs::rename(tmp, target(k)).map_err(|e| {
                format!(
                    "cannot rename {} to {}: {e}",
                    tmp.display(),
                    target(k).display()
                )
            })?;
        }
        self.files.clear();
        if complete {
            for name in PARTIAL {
                let _ = std::fs::remove_file(self.dir.join(name));
            }
        }
        Ok(Written {
            probes: target(0),
            summary: target(1),
            energy: self.energy.then(|| target(2)),
        })
    }
}

impl Drop for RunOutputs {
    /// Removes the temporary files of a run whose results were not committed.
    fn drop(&mut self) {
        for (_, tmp, _) in &self.files {
            let _ = std::fs::remove_file(tmp);
        }
    }
}
