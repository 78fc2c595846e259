//! The parameter store: numbered parameters #1..#5602 with LinuxCNC's system layout, named
//! global (`#<_name>`) and local (`#<name>`, one scope per subroutine call) parameters, and
//! the parameter file (LinuxCNC `.var` format) written atomically.

use std::collections::HashMap;
use std::io::Write;
use std::path::Path;

use crate::block::MAX_PARAMETER;

/// System parameter numbers (LinuxCNC layout).
pub mod sys {
    /// Probe trip position X..W (9 values).
    pub const PROBE: usize = 5061;
    /// 1 if the last probe tripped.
    pub const PROBE_OK: usize = 5070;
    /// G28 home X..W.
    pub const G28: usize = 5161;
    /// G30 home X..W.
    pub const G30: usize = 5181;
    /// 1 while G92 offsets are applied.
    pub const G92_APPLIED: usize = 5210;
    /// G92 offset X..W.
    pub const G92: usize = 5211;
    /// Active coordinate system 1..9.
    pub const COORD_SYSTEM: usize = 5220;
    /// G54 offset X..W, then rotation (5230); G55 is 20 higher, ... G59.3 at 5381.
    pub const G54: usize = 5221;
    /// Result of the last M66.
    pub const INPUT: usize = 5399;
    /// Tool number in the spindle.
    pub const TOOL: usize = 5400;
    /// Tool offsets X..W (5401..5409), diameter 5410, front/back angle, orientation.
    pub const TOOL_OFFSET: usize = 5401;
    /// Current position X..W in the active coordinate system.
    pub const POSITION: usize = 5420;
}

/// Numbered parameters saved in the parameter file.
pub fn is_persistent(index: usize) -> bool {
    (5161..=5169).contains(&index)
        || (5181..=5189).contains(&index)
        || (5210..=5219).contains(&index)
        || index == 5220
        || ((5221..=5390).contains(&index) && (index - 5221) % 20 < 10)
}

/// Names of the predefined read-only named parameters (without the leading `_`).
pub const PREDEFINED: &[&str] = &[
    "vmajor",
    "vminor",
    "line",
    "motion_mode",
    "plane",
    "ccomp",
    "metric",
    "imperial",
    "absolute",
    "incremental",
    "inverse_time",
    "units_per_minute",
    "units_per_rev",
    "coord_system",
    "tool_offset",
    "retract_r_plane",
    "retract_old_z",
    "spindle_rpm_mode",
    "spindle_css_mode",
    "ijk_absolute_mode",
    "lathe_diameter_mode",
    "lathe_radius_mode",
    "spindle_on",
    "spindle_cw",
    "mist",
    "flood",
    "speed_override",
    "feed_override",
    "adaptive_feed",
    "feed_hold",
    "feed",
    "rpm",
    "x",
    "y",
    "z",
    "a",
    "b",
    "c",
    "u",
    "v",
    "w",
    "abs_x",
    "abs_y",
    "abs_z",
    "abs_a",
    "abs_b",
    "abs_c",
    "abs_u",
    "abs_v",
    "abs_w",
    "current_tool",
    "current_pocket",
    "selected_tool",
    "selected_pocket",
    "value",
    "value_returned",
    "call_level",
    "remap_level",
    "task",
];

/// True if `name` (lower case, with its leading `_`) is a predefined read-only parameter.
pub fn is_predefined(name: &str) -> bool {
    name.strip_prefix('_')
        .is_some_and(|n| PREDEFINED.contains(&n) && n != "value" && n != "value_returned")
}

/// Numbered and named parameter values.
#[derive(Clone, Debug)]
pub struct Parameters {
    numbered: Vec<f64>,
    globals: HashMap<String, f64>,
    /// Local scopes, innermost last; index 0 is the main program's.
    locals: Vec<HashMap<String, f64>>,
    /// Numbered parameters that came from the parameter file (written back too).
    from_file: Vec<usize>,
}

impl Default for Parameters {
    fn default() -> Self {
        let mut p = Parameters {
            numbered: vec![0.0; MAX_PARAMETER + 1],
            globals: HashMap::new(),
            locals: vec![HashMap::new()],
            from_file: Vec::new(),
        };
        p.numbered[sys::COORD_SYSTEM] = 1.0;
        p
    }
}

/// A parameter file could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum ParamFileError {
    /// Reading or writing failed.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// A line is not `NUMBER VALUE`.
    #[error("{path}:{line}: {message}")]
    Format {
        /// The file.
        path: String,
        /// 1-based line.
        line: usize,
        /// What is wrong.
        message: String,
    },
}

impl Parameters {
    /// Fresh parameters: all zero, coordinate system 1 (G54).
    pub fn new() -> Parameters {
        Parameters::default()
    }

    /// Value of `#index` (0 outside 1..=5602).
    pub fn get(&self, index: usize) -> f64 {
        self.numbered.get(index).copied().unwrap_or(0.0)
    }

    /// Sets `#index` (ignored outside 1..=5602).
    pub fn set(&mut self, index: usize, value: f64) {
        if let Some(p) = self.numbered.get_mut(index) {
            *p = value;
        }
    }

    /// A named parameter as the program sees it (global if it starts with `_`, else local to
    /// the current call level). Predefined parameters are not stored here.
    pub fn named(&self, name: &str) -> Option<f64> {
        if name.starts_with('_') {
            self.globals.get(name).copied()
        } else {
            self.locals.last().and_then(|l| l.get(name).copied())
        }
    }

    /// Sets a named parameter (global or local by its name).
    pub fn set_named(&mut self, name: &str, value: f64) {
        if name.starts_with('_') {
            if let Some(v) = self.globals.get_mut(name) {
                *v = value;
            } else {
                self.globals.insert(name.to_string(), value);
            }
        } else if let Some(l) = self.locals.last_mut() {
            if let Some(v) = l.get_mut(name) {
                *v = value;
            } else {
                l.insert(name.to_string(), value);
            }
        }
    }

    pub(crate) fn push_scope(&mut self) {
        self.locals.push(HashMap::new());
    }

    pub(crate) fn pop_scope(&mut self) {
        if self.locals.len() > 1 {
            self.locals.pop();
        }
    }

    pub(crate) fn reset_scopes(&mut self) {
        self.locals.truncate(1);
    }

    /// Reads a LinuxCNC `.var` parameter file (`NUMBER VALUE` per line; other lines ignored
    /// when they do not start with a number).
    pub fn load(path: &Path) -> Result<Parameters, ParamFileError> {
        let text = std::fs::read_to_string(path).map_err(|source| ParamFileError::Io {
            path: path.display().to_string(),
            source,
        })?;
        let mut p = Parameters::new();
        for (n, line) in text.lines().enumerate() {
            let mut it = line.split_whitespace();
            let Some(first) = it.next() else { continue };
            let Ok(index) = first.parse::<usize>() else {
                continue;
            };
            let bad = |message: &str| ParamFileError::Format {
                path: path.display().to_string(),
                line: n + 1,
                message: message.to_string(),
            };
            if index == 0 || index > MAX_PARAMETER {
                return Err(bad("parameter number out of range"));
            }
            let value: f64 = it
                .next()
                .and_then(|v| v.parse().ok())
                .ok_or_else(|| bad("value missing or not a number"))?;
            p.numbered[index] = value;
            p.from_file.push(index);
        }
        Ok(p)
    }

    /// Writes the persistent parameters (work offsets, G92, G28/G30 homes, coordinate
    /// system, and whatever else came from the file) in `.var` format, atomically: a
    /// temporary file next to `path` is written, synced, then renamed over it.
    pub fn save(&self, path: &Path) -> Result<(), ParamFileError> {
        let io = |source| ParamFileError::Io {
            path: path.display().to_string(),
            source,
        };
        let mut text = Vec::with_capacity(8192);
        for index in 1..=MAX_PARAMETER {
            if is_persistent(index) || self.from_file.contains(&index) {
                let _ = writeln!(text, "{index}\t{:.6}", self.numbered[index]);
            }
        }
        let dir = path.parent().filter(|d| !d.as_os_str().is_empty());
        let name = path.file_name().map(|n| n.to_string_lossy().into_owned());
        let tmp = match dir {
            Some(d) => d.join(format!(".{}.tmp", name.unwrap_or_default())),
            None => Path::new(&format!(".{}.tmp", name.unwrap_or_default())).to_path_buf(),
        };
        let mut f = std::fs::File::create(&tmp).map_err(io)?;
        f.write_all(&text).map_err(io)?;
        f.sync_all().map_err(io)?;
        drop(f);
        std::fs::rename(&tmp, path).map_err(io)?;
        if let Some(d) = dir {
            // Make the rename itself durable.
            if let Ok(dirf) = std::fs::File::open(d) {
                let _ = dirf.sync_all();
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn persistent_layout_matches_linuxcnc() {
        assert!(is_persistent(5161) && is_persistent(5169));
        assert!(is_persistent(5220) && is_persistent(5221) && is_persistent(5230));
        assert!(!is_persistent(5231) && is_persistent(5241) && is_persistent(5390));
        assert!(!is_persistent(5400) && !is_persistent(5160));
    }

    #[test]
    fn var_file_round_trip_is_atomic_and_complete() {
        let dir = std::env::temp_dir().join(format!("rtcnc-var-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("test.var");
        std::fs::write(&path, "5220\t2.000000\n31\t7.5\n").unwrap();
        let mut p = Parameters::load(&path).unwrap();
        assert_eq!(p.get(5220), 2.0);
        assert_eq!(p.get(31), 7.5);
        p.set(5241, 12.5);
        p.save(&path).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.contains("5241\t12.500000\n"));
        assert!(text.contains("31\t7.500000\n"));
        assert!(text.contains("5161\t0.000000\n"));
        assert!(!dir.join(".test.var.tmp").exists());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
