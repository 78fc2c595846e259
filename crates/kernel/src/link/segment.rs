//! Creating, naming and mapping the segment: the machine creates it under a temporary name,
//! fills in the header and only then renames it into place, so a client never maps a
//! half-made segment; a client checks the magic, the layout version and the size before it
//! touches anything else.

use std::fs::{File, OpenOptions};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::Ordering;

use memmap2::MmapRaw;

use super::layout::{Header, LAYOUT_VERSION, MAGIC, Segment};

/// Why the segment could not be created or attached.
#[derive(Debug, thiserror::Error)]
pub enum LinkError {
    /// The name is not a plain file name.
    #[error("segment name {0:?}: use letters, digits, '.', '_' and '-' (at most 64)")]
    BadName(String),
    /// No machine runs under this name.
    #[error("no machine segment at {0}")]
    Absent(PathBuf),
    /// Reading, writing or mapping the file failed.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// Not an rtcnc segment.
    #[error("{0}: not an rtcnc machine segment (bad magic)")]
    NotASegment(PathBuf),
    /// Another layout.
    #[error(
        "{path}: the machine's segment has layout version {found}, this program reads \
         version {expected}: run a machine and an API of the same rtcnc"
    )]
    Version {
        /// The file.
        path: PathBuf,
        /// The segment's version.
        found: u32,
        /// Ours.
        expected: u32,
    },
    /// The same version number but another size: a build mismatch.
    #[error("{path}: segment of {found} bytes, this program's layout has {expected}")]
    Size {
        /// The file.
        path: PathBuf,
        /// The segment's size.
        found: u64,
        /// Ours.
        expected: u64,
    },
    /// Another client is attached and alive.
    #[error("another API process (pid {0}) is attached to this machine")]
    Busy(u32),
}

impl LinkError {
    /// Stable code.
    pub fn code(&self) -> &'static str {
        match self {
            LinkError::BadName(_) => "link.bad_name",
            LinkError::Absent(_) => "link.absent",
            LinkError::Io { .. } => "link.io",
            LinkError::NotASegment(_) => "link.not_a_segment",
            LinkError::Version { .. } => "link.version",
            LinkError::Size { .. } => "link.size",
            LinkError::Busy(_) => "link.busy",
        }
    }
}

/// The folder of the segments: `/dev/shm`, or `RTCNC_SHM_DIR` when set (tests, systems
/// without /dev/shm).
pub fn segment_dir() -> PathBuf {
    std::env::var_os("RTCNC_SHM_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("/dev/shm"))
}

/// The file of the segment called `name`.
pub fn segment_path(name: &str) -> Result<PathBuf, LinkError> {
    let ok = !name.is_empty()
        && name.len() <= 64
        && !name.starts_with('.')
        && name
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b"._-".contains(&b));
    if !ok {
        return Err(LinkError::BadName(name.to_string()));
    }
    Ok(segment_dir().join(name))
}

/// A mapped segment. Dropping the last clone unmaps it; a clone only counts a reference
/// (the real-time tasks clone it without allocating).
#[derive(Clone)]
pub struct Mapping {
    inner: Arc<Mapped>,
}

struct Mapped {
    map: MmapRaw,
    path: PathBuf,
}

impl std::fmt::Debug for Mapping {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Mapping({})", self.inner.path.display())
    }
}

// SAFETY: the mapping is only reached through `&Segment`, whose fields are atomics and the
// executive's shared-memory cells (Sync).
unsafe impl Send for Mapping {}
// SAFETY: as above.
unsafe impl Sync for Mapping {}

impl Mapping {
    /// The segment.
    pub fn segment(&self) -> &Segment {
        // SAFETY: the mapping is at least `size_of::<Segment>()` long (checked when it was
        // made or opened), page-aligned, and lives as long as `self`; every field of
        // `Segment` is valid for any bytes a process may leave there except that the
        // cells' counters must be sane, which the cells check themselves.
        unsafe { &*self.inner.map.as_ptr().cast::<Segment>() }
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.inner.path
    }

    /// Makes a new segment called `name` (replacing a stale one of a machine that died):
    /// written under a temporary name, header filled by `init`, then renamed into place.
    pub fn create(name: &str, init: impl FnOnce(&mut Header)) -> Result<Mapping, LinkError> {
        let path = segment_path(name)?;
        let tmp = path.with_file_name(format!(".{name}.{}", std::process::id()));
        let io = |source| LinkError::Io {
            path: path.clone(),
            source,
        };
        let size = std::mem::size_of::<Segment>() as u64;
        let file = OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(true)
            .open(&tmp)
            .map_err(io)?;
        file.set_len(size).map_err(io)?;
        let map = MmapRaw::map_raw(&file).map_err(io)?;
        let seg = map.as_mut_ptr().cast::<Segment>();
        // SAFETY: a fresh mapping of `size` zeroed bytes, page-aligned, ours alone until
        // renamed; all zeros is a valid `Segment` except for the cells, initialised next.
        unsafe {
            use rtcnc_rt::{SeqlockCell, SpscCell};
            use std::ptr::addr_of_mut;
            SpscCell::init_at(addr_of_mut!((*seg).commands));
            SpscCell::init_at(addr_of_mut!((*seg).urgent));
            SpscCell::init_at(addr_of_mut!((*seg).events));
            SpscCell::init_at(addr_of_mut!((*seg).trace));
            SpscCell::init_at(addr_of_mut!((*seg).requests));
            SpscCell::init_at(addr_of_mut!((*seg).replies));
            SeqlockCell::init_at(addr_of_mut!((*seg).status), Default::default());
            SeqlockCell::init_at(addr_of_mut!((*seg).timing), Default::default());
            SeqlockCell::init_at(addr_of_mut!((*seg).watch), Default::default());
            let header = &mut *addr_of_mut!((*seg).header);
            header.layout_version = LAYOUT_VERSION;
            header.header_size = std::mem::size_of::<Header>() as u32;
            header.segment_size = size;
            header.machine_pid = std::process::id();
            init(header);
            header.magic.store(MAGIC, Ordering::Release);
        }
        std::fs::rename(&tmp, &path).map_err(io)?;
        Ok(Mapping {
            inner: Arc::new(Mapped { map, path }),
        })
    }

    /// Maps the segment called `name` and checks it.
    pub fn open(name: &str) -> Result<Mapping, LinkError> {
        let path = segment_path(name)?;
        let file = match OpenOptions::new().read(true).write(true).open(&path) {
            Ok(f) => f,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                return Err(LinkError::Absent(path));
            }
            Err(source) => return Err(LinkError::Io { path, source }),
        };
        Self::check_and_map(file, path)
    }

    fn check_and_map(file: File, path: PathBuf) -> Result<Mapping, LinkError> {
        let io = |source| LinkError::Io {
            path: path.clone(),
            source,
        };
        let len = file.metadata().map_err(io)?.len();
        let expected = std::mem::size_of::<Segment>() as u64;
        if len < std::mem::size_of::<Header>() as u64 {
            return Err(LinkError::NotASegment(path));
        }
        let map = MmapRaw::map_raw(&file).map_err(io)?;
        let header = map.as_ptr().cast::<Header>();
        // SAFETY: at least a header's bytes are mapped; the header's fields are plain
        // integers (any bytes are a value).
        let (magic, version, size) = unsafe {
            (
                (*header).magic.load(Ordering::Acquire),
                (*header).layout_version,
                (*header).segment_size,
            )
        };
        if magic != MAGIC {
            return Err(LinkError::NotASegment(path));
        }
        if version != LAYOUT_VERSION {
            return Err(LinkError::Version {
                path,
                found: version,
                expected: LAYOUT_VERSION,
            });
        }
        if size != expected || len < expected {
            return Err(LinkError::Size {
                path,
                found: size.min(len),
                expected,
            });
        }
        Ok(Mapping {
            inner: Arc::new(Mapped { map, path }),
        })
    }

    /// Removes the segment's name, if it is still this mapping's file (a newer machine may
    /// have replaced it).
    pub fn unlink(&self) {
        let mine = self.segment().header.instance;
        if let Ok(other) = Mapping::open_path(self.path()) {
            if other.segment().header.instance == mine {
                let _ = std::fs::remove_file(self.path());
            }
        }
    }

    fn open_path(path: &Path) -> Result<Mapping, LinkError> {
        let file = OpenOptions::new()
            .read(true)
            .write(true)
            .open(path)
            .map_err(|source| LinkError::Io {
                path: path.to_path_buf(),
                source,
            })?;
        Self::check_and_map(file, path.to_path_buf())
    }
}

/// CLOCK_MONOTONIC in ns: the same clock in every process of the machine (the vDSO reads it
/// without a system call).
pub fn monotonic_ns() -> u64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: a valid out-pointer.
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) };
    (ts.tv_sec as u64)
        .saturating_mul(1_000_000_000)
        .saturating_add(ts.tv_nsec as u64)
}
