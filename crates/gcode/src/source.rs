//! Program text, read a line at a time from files (or one MDI line), with byte offsets so
//! that loops and subroutine calls jump by seeking instead of keeping lines in memory.

use std::fs::File;
use std::io::{BufRead, BufReader, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use crate::canon::FileId;

/// Longest line accepted (LinuxCNC accepts 256 characters; CAM comments can be longer).
pub const MAX_LINE: usize = 16 * 1024;

/// A place in a file: the start of a line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Location {
    pub file: FileId,
    /// Byte offset of the start of the line.
    pub offset: u64,
    /// 1-based number of that line.
    pub line: u32,
}

impl Location {
    /// The canonical commands' source of this line (no N word yet).
    pub fn source(self) -> crate::canon::Source {
        crate::canon::Source {
            file: self.file,
            line: self.line,
            n: None,
        }
    }
}

/// Where the text of a program comes from.
enum Text {
    File(BufReader<File>),
    Memory(std::io::Cursor<Vec<u8>>),
}

impl Text {
    fn reader(&mut self) -> &mut dyn BufRead {
        match self {
            Text::File(f) => f,
            Text::Memory(m) => m,
        }
    }

    /// Moves to `offset`; `from` is the current position. Within the buffer of a file no
    /// data is read again (loops and calls jump back and forth a lot).
    fn seek(&mut self, offset: u64, from: u64) -> std::io::Result<()> {
        match self {
            Text::File(f) => {
                let delta = i64::try_from(offset)
                    .ok()
                    .zip(i64::try_from(from).ok())
                    .map(|(a, b)| a - b);
                match delta {
                    Some(d) => f.seek_relative(d),
                    None => f.seek(SeekFrom::Start(offset)).map(|_| ()),
                }
            }
            Text::Memory(m) => {
                m.set_position(offset);
                Ok(())
            }
        }
    }
}

struct OpenFile {
    name: Arc<str>,
    path: PathBuf,
    reader: Option<Text>,
    /// Offset of the next line to read.
    offset: u64,
    /// Number of the last line read.
    line: u32,
}

/// Why a line could not be read.
pub(crate) enum ReadLineError {
    Io(std::io::Error),
    TooLong,
}

/// All files of one run and the one being read.
pub(crate) struct Sources {
    files: Vec<OpenFile>,
    current: Option<FileId>,
    /// The last line read (without its newline).
    pub line: Vec<u8>,
    /// Where the last line read started.
    pub line_start: Location,
}

impl Sources {
    pub fn new() -> Sources {
        Sources {
            files: Vec::new(),
            current: None,
            line: Vec::with_capacity(256),
            line_start: Location {
                file: 0,
                offset: 0,
                line: 0,
            },
        }
    }

    /// Drops every file; the next `open` gets id 0.
    pub fn clear(&mut self) {
        self.files.clear();
        self.current = None;
    }

    /// Opens `path` (or finds it already open) and returns its id. Does not switch to it.
    pub fn open(&mut self, path: &Path, name: &str) -> std::io::Result<FileId> {
        if let Some(i) = self.files.iter().position(|f| f.path == path) {
            return Ok(i as FileId);
        }
        let file = File::open(path)?;
        if self.files.len() >= usize::from(FileId::MAX) {
            return Err(std::io::Error::other("too many files"));
        }
        self.files.push(OpenFile {
            name: Arc::from(name),
            path: path.to_path_buf(),
            reader: Some(Text::File(BufReader::with_capacity(8 * 1024, file))),
            offset: 0,
            line: 0,
        });
        Ok((self.files.len() - 1) as FileId)
    }

    /// Adds a program held in memory (named `name`) and returns its id.
    pub fn open_text(&mut self, name: &str, text: Vec<u8>) -> std::io::Result<FileId> {
        if self.files.len() >= usize::from(FileId::MAX) {
            return Err(std::io::Error::other("too many files"));
        }
        self.files.push(OpenFile {
            name: Arc::from(name),
            path: PathBuf::new(),
            reader: Some(Text::Memory(std::io::Cursor::new(text))),
            offset: 0,
            line: 0,
        });
        Ok((self.files.len() - 1) as FileId)
    }

    /// Name of file `id` as it was given.
    pub fn name(&self, id: FileId) -> Arc<str> {
        self.files
            .get(usize::from(id))
            .map(|f| f.name.clone())
            .unwrap_or_else(|| Arc::from("<mdi>"))
    }

    /// Path of file `id`.
    pub fn path(&self, id: FileId) -> Option<&Path> {
        self.files.get(usize::from(id)).map(|f| f.path.as_path())
    }

    pub fn current(&self) -> Option<FileId> {
        self.current
    }

    /// Where the next line of the current file starts.
    pub fn next_location(&self) -> Option<Location> {
        let id = self.current?;
        let f = &self.files[usize::from(id)];
        Some(Location {
            file: id,
            offset: f.offset,
            line: f.line + 1,
        })
    }

    /// Continues reading at `loc` (seeking only when needed).
    pub fn jump(&mut self, loc: Location) -> std::io::Result<()> {
        let f = self
            .files
            .get_mut(usize::from(loc.file))
            .ok_or_else(|| std::io::Error::other("no such file"))?;
        let reader = f
            .reader
            .as_mut()
            .ok_or_else(|| std::io::Error::other("file closed"))?;
        if f.offset != loc.offset {
            reader.seek(loc.offset, f.offset)?;
            f.offset = loc.offset;
        }
        f.line = loc.line.saturating_sub(1);
        self.current = Some(loc.file);
        Ok(())
    }

    /// Reads the next line of the current file into `self.line`. `Ok(false)` at end of file.
    pub fn read_line(&mut self) -> Result<bool, ReadLineError> {
        self.line.clear();
        let Some(id) = self.current else {
            return Ok(false);
        };
        let f = &mut self.files[usize::from(id)];
        let Some(reader) = f.reader.as_mut() else {
            return Ok(false);
        };
        let n = reader
            .reader()
            .take(MAX_LINE as u64 + 1)
            .read_until(b'\n', &mut self.line)
            .map_err(ReadLineError::Io)?;
        if n == 0 {
            return Ok(false);
        }
        self.line_start = Location {
            file: id,
            offset: f.offset,
            line: f.line.saturating_add(1),
        };
        f.offset += n as u64;
        f.line = f.line.saturating_add(1);
        if self.line.last() == Some(&b'\n') {
            self.line.pop();
            if self.line.last() == Some(&b'\r') {
                self.line.pop();
            }
        } else if n > MAX_LINE {
            // The rest of the line goes too, so that it is refused once and the lines after
            // it keep their numbers.
            let rest = reader
                .reader()
                .skip_until(b'\n')
                .map_err(ReadLineError::Io)?;
            f.offset += rest as u64;
            return Err(ReadLineError::TooLong);
        }
        Ok(true)
    }

    /// Stops reading files (after an MDI command read a subroutine for itself).
    pub fn detach(&mut self) {
        self.current = None;
    }

    /// Sets the one line of an MDI command as the line to execute.
    pub fn set_mdi_line(&mut self, text: &str) {
        self.line.clear();
        self.line.extend_from_slice(text.as_bytes());
        self.current = None;
        self.line_start = Location {
            file: FileId::MAX,
            offset: 0,
            line: 1,
        };
    }
}
