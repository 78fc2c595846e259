//! RETAIN variables: snapshots, the atomic retain file, restore.

use std::fs;
use std::io::Write as _;

use super::*;

impl Runtime {
    /// Copies the RETAIN variables into a new snapshot (allocates: take one at start-up,
    /// then refresh it with [`Runtime::update_retain_snapshot`]).
    ///
    /// Real-time: no (allocates).
    pub fn retain_snapshot(&self) -> RetainSnapshot {
        let mut snap = RetainSnapshot {
            leaves: Arc::clone(&self.retain),
            values: vec![0; self.retain.iter().map(|l| bytes_of(&l.ty)).sum()],
        };
        self.update_retain_snapshot(&mut snap);
        snap
    }

    /// Refreshes a snapshot taken from this runtime, without allocating: cheap enough for
    /// the PLC task, which then hands the snapshot to a thread that may block on the disk.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn update_retain_snapshot(&self, snap: &mut RetainSnapshot) {
        let mut at = 0usize;
        for l in self.retain.iter() {
            let n = bytes_of(&l.ty);
            let src = l.slot as usize;
            if let (Some(dst), Some(s)) = (
                snap.values.get_mut(at..at + n),
                self.vm.mem.get(src..src + n),
            ) {
                dst.copy_from_slice(s);
            }
            at += n;
        }
    }

    /// Writes the RETAIN variables to `path` atomically (see [`RetainSnapshot::save`]).
    /// Blocks on the disk: call it outside the real-time task.
    ///
    /// Real-time: no (allocates, writes a file).
    pub fn save_retain(&self, path: &Path) -> std::io::Result<()> {
        self.retain_snapshot().save(path)
    }

    /// Restores RETAIN variables from `path`. Entries whose name no longer exists or whose
    /// value no longer fits are skipped and counted; a missing file restores nothing.
    ///
    /// Real-time: no (allocates, reads a file).
    pub fn load_retain(&mut self, path: &Path) -> std::io::Result<RetainReport> {
        let text = match fs::read_to_string(path) {
            Ok(t) => t,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                return Ok(RetainReport::default());
            }
            Err(e) => return Err(e),
        };
        let mut report = RetainReport::default();
        for line in text.lines() {
            let line = line.trim();
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            let Some((name, value)) = line.split_once(" = ") else {
                report.skipped += 1;
                continue;
            };
            let Some(leaf) = self
                .retain
                .iter()
                .find(|l| l.path.eq_ignore_ascii_case(name.trim()))
            else {
                report.skipped += 1;
                continue;
            };
            let r = VarRef {
                slot: leaf.slot,
                ty: leaf.ty.clone(),
                bit: None,
                located_input: false,
            };
            let value = value.trim();
            let parsed = if r.ty.is_string() {
                let inner = value
                    .strip_prefix('\'')
                    .and_then(|v| v.strip_suffix('\''))
                    .unwrap_or(value);
                Ok(Value::String(
                    inner
                        .replace("$N", "\n")
                        .replace("$'", "'")
                        .replace("$$", "$"),
                ))
            } else {
                self.parse_value(&r, value)
            };
            match parsed.and_then(|v| self.write(&r, &v)) {
                Ok(()) => report.restored += 1,
                Err(_) => report.skipped += 1,
            }
        }
        Ok(report)
    }
}

/// The RETAIN variables at one moment, for writing to disk outside the PLC task.
#[derive(Debug, Clone)]
pub struct RetainSnapshot {
    leaves: Arc<[RetainLeaf]>,
    values: Vec<u8>,
}

/// Two snapshots of the same program are equal when every retained value is: a saver uses
/// this to write the file only when something changed.
impl PartialEq for RetainSnapshot {
    fn eq(&self, other: &Self) -> bool {
        Arc::ptr_eq(&self.leaves, &other.leaves) && self.values == other.values
    }
}

impl RetainSnapshot {
    /// Writes `name = value` lines to a temporary file in the same directory, fsyncs it,
    /// renames it over `path` and fsyncs the directory: a crash leaves either the old or
    /// the new file, never a torn one.
    ///
    /// Real-time: no (allocates, writes a file).
    pub fn save(&self, path: &Path) -> std::io::Result<()> {
        let mut text = String::from("# rtcnc-plc retained variables v1\n");
        let mut at = 0usize;
        for l in self.leaves.iter() {
            let shown = match value_at(&self.values, at, &l.ty) {
                Value::String(s) => {
                    format!(
                        "'{}'",
                        s.replace('$', "$$").replace('\'', "$'").replace('\n', "$N")
                    )
                }
                Value::Real(x) => format!("{x:?}"),
                v => v.to_string(),
            };
            text.push_str(&format!("{} = {}\n", l.path, shown));
            at += bytes_of(&l.ty);
        }
        let dir = path
            .parent()
            .filter(|p| !p.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| "retain".into());
        let tmp = dir.join(format!(".{name}.tmp{}", std::process::id()));
        {
            let mut f = fs::File::create(&tmp)?;
            f.write_all(text.as_bytes())?;
            f.sync_all()?;
        }
        fs::rename(&tmp, path)?;
        if let Ok(d) = fs::File::open(dir) {
            let _ = d.sync_all();
        }
        Ok(())
    }
}

/// What [`Runtime::load_retain`] did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RetainReport {
    /// Values restored.
    pub restored: usize,
    /// Entries skipped (unknown name or value that does not fit).
    pub skipped: usize,
}

pub(super) fn retain_leaves(p: &Program) -> Vec<RetainLeaf> {
    p.leaves()
        .into_iter()
        .filter(|l| l.retain)
        .map(|l| RetainLeaf {
            path: l.path,
            slot: l.slot,
            ty: l.ty,
        })
        .collect()
}
