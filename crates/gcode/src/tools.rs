//! Tool tables in LinuxCNC's `.tbl` format:
//! `T<number> P<pocket> [X.. Y.. Z.. A.. B.. C.. U.. V.. W..] [D<diameter>] [I<front angle>]
//! [J<back angle>] [Q<orientation>] [;comment]`, one tool per line.

use std::io::Write;
use std::path::Path;

use crate::canon::Pose;

/// One tool.
#[derive(Clone, Debug, PartialEq)]
pub struct Tool {
    /// T number.
    pub number: i32,
    /// P: pocket.
    pub pocket: i32,
    /// Offsets X..W (length offset is `offset.z` on a mill).
    pub offset: Pose,
    /// D: diameter.
    pub diameter: f64,
    /// I: lathe front angle.
    pub front_angle: f64,
    /// J: lathe back angle.
    pub back_angle: f64,
    /// Q: lathe orientation.
    pub orientation: i32,
    /// Text after `;`.
    pub comment: String,
}

impl Tool {
    /// An empty tool of this number and pocket.
    pub fn new(number: i32, pocket: i32) -> Tool {
        Tool {
            number,
            pocket,
            offset: Pose::ZERO,
            diameter: 0.0,
            front_angle: 0.0,
            back_angle: 0.0,
            orientation: 0,
            comment: String::new(),
        }
    }
}

/// A tool table. Values are in the machine's (user) units.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ToolTable {
    tools: Vec<Tool>,
}

/// A tool table file could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum ToolTableError {
    /// Reading or writing failed.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// A line cannot be read.
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

impl ToolTable {
    /// An empty table.
    pub fn new() -> ToolTable {
        ToolTable::default()
    }

    /// Reads a `.tbl` file.
    pub fn load(path: &Path) -> Result<ToolTable, ToolTableError> {
        let text = std::fs::read_to_string(path).map_err(|source| ToolTableError::Io {
            path: path.display().to_string(),
            source,
        })?;
        ToolTable::parse(&text).map_err(|(line, message)| ToolTableError::Format {
            path: path.display().to_string(),
            line,
            message,
        })
    }

    /// Parses `.tbl` text; errors carry the 1-based line and a message.
    pub fn parse(text: &str) -> Result<ToolTable, (usize, String)> {
        let mut table = ToolTable::new();
        for (n, raw) in text.lines().enumerate() {
            let (data, comment) = match raw.find(';') {
                Some(i) => (&raw[..i], raw[i + 1..].trim().to_string()),
                None => (raw, String::new()),
            };
            if data.trim().is_empty() {
                continue;
            }
            let mut tool = Tool::new(-1, -1);
            tool.comment = comment;
            for word in data.split_whitespace() {
                let mut chars = word.chars();
                let letter = chars.next().unwrap_or(' ').to_ascii_uppercase();
                let value: f64 = chars
                    .as_str()
                    .parse()
                    .map_err(|_| (n + 1, format!("bad value in word '{word}'")))?;
                match letter {
                    'T' => tool.number = value as i32,
                    'P' => tool.pocket = value as i32,
                    'X' => tool.offset.x = value,
                    'Y' => tool.offset.y = value,
                    'Z' => tool.offset.z = value,
                    'A' => tool.offset.a = value,
                    'B' => tool.offset.b = value,
                    'C' => tool.offset.c = value,
                    'U' => tool.offset.u = value,
                    'V' => tool.offset.v = value,
                    'W' => tool.offset.w = value,
                    'D' => tool.diameter = value,
                    'I' => tool.front_angle = value,
                    'J' => tool.back_angle = value,
                    'Q' => tool.orientation = value as i32,
                    _ => return Err((n + 1, format!("unknown word '{word}'"))),
                }
            }
            if tool.number < 0 {
                return Err((n + 1, "T word missing".to_string()));
            }
            if tool.pocket < 0 {
                tool.pocket = tool.number;
            }
            table.set(tool);
        }
        Ok(table)
    }

    /// The tool with this number.
    pub fn get(&self, number: i32) -> Option<&Tool> {
        self.tools.iter().find(|t| t.number == number)
    }

    /// Adds or replaces the tool with `tool.number`.
    pub fn set(&mut self, tool: Tool) {
        match self.tools.iter_mut().find(|t| t.number == tool.number) {
            Some(t) => *t = tool,
            None => self.tools.push(tool),
        }
    }

    /// All tools in table order.
    pub fn tools(&self) -> &[Tool] {
        &self.tools
    }

    /// The table in `.tbl` format.
    pub fn to_text(&self) -> String {
        let mut text = Vec::new();
        for t in &self.tools {
            let _ = write!(text, "T{} P{}", t.number, t.pocket);
            let o = t.offset.to_array();
            for (letter, v) in "XYZABCUVW".chars().zip(o) {
                if v != 0.0 {
                    let _ = write!(text, " {letter}{v:+.6}");
                }
            }
            if t.diameter != 0.0 {
                let _ = write!(text, " D{:.6}", t.diameter);
            }
            if t.front_angle != 0.0 {
                let _ = write!(text, " I{:+.6}", t.front_angle);
            }
            if t.back_angle != 0.0 {
                let _ = write!(text, " J{:+.6}", t.back_angle);
            }
            if t.orientation != 0 {
                let _ = write!(text, " Q{}", t.orientation);
            }
            let _ = writeln!(text, " ;{}", t.comment);
        }
        String::from_utf8(text).unwrap_or_default()
    }

    /// Writes the table in `.tbl` format atomically (temporary file, fsync, rename).
    pub fn save(&self, path: &Path) -> Result<(), ToolTableError> {
        let io = |source| ToolTableError::Io {
            path: path.display().to_string(),
            source,
        };
        let text = self.to_text().into_bytes();
        let tmp = path.with_extension("tbl.tmp");
        let mut f = std::fs::File::create(&tmp).map_err(io)?;
        f.write_all(&text).map_err(io)?;
        f.sync_all().map_err(io)?;
        drop(f);
        std::fs::rename(&tmp, path).map_err(io)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_linuxcnc_tbl() {
        let t = ToolTable::parse("T1 P1 Z0.511 D3 ;3mm end mill\n\nT4 P4 Z10 D16 ;16mm\n").unwrap();
        let t1 = t.get(1).unwrap();
        assert_eq!(t1.offset.z, 0.511);
        assert_eq!(t1.diameter, 3.0);
        assert_eq!(t1.comment, "3mm end mill");
        assert_eq!(t.get(4).unwrap().pocket, 4);
        assert!(t.get(2).is_none());
        assert_eq!(ToolTable::parse("T1 P1 K3").unwrap_err().0, 1);
    }

    #[test]
    fn save_and_load_round_trip() {
        let dir = std::env::temp_dir().join(format!("rtcnc-tbl-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("t.tbl");
        let mut t = ToolTable::parse("T7 P3 Z-1.25 D6.35 Q2 ;x\n").unwrap();
        t.set(Tool::new(9, 9));
        t.save(&path).unwrap();
        assert_eq!(ToolTable::load(&path).unwrap(), t);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
