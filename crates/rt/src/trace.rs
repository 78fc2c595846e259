//! Trace: one preallocated, lock-free event buffer per executive thread ("lane"), exported
//! as Chrome trace-event JSON (Perfetto and chrome://tracing open it).
//!
//! Each lane has exactly one writer: the thread that runs its tasks. A lane is a ring: when
//! it is full the oldest events are overwritten and counted as dropped. Export happens when
//! the writers are quiet (after a real-time run stopped, or between virtual-time steps).

use std::cell::UnsafeCell;
use std::fmt::Write as _;
use std::sync::atomic::{AtomicU64, Ordering};

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum EventKind {
    /// A body run: `time` is its start, `arg` its duration.
    Span,
    /// A user mark from `Context::mark`.
    Mark,
    /// A fault: `arg` is the fault detail, `label` its code.
    Fault,
}

#[derive(Debug, Clone, Copy)]
pub(crate) struct TraceEvent {
    pub time: u64,
    pub kind: EventKind,
    pub task: u32,
    pub label: &'static str,
    pub arg: u64,
}

const EMPTY: TraceEvent = TraceEvent {
    time: 0,
    kind: EventKind::Mark,
    task: 0,
    label: "",
    arg: 0,
};

pub(crate) struct Lane {
    name: String,
    slots: Box<[UnsafeCell<TraceEvent>]>,
    head: AtomicU64,
}

// SAFETY: a lane has a single writer (the runner gives each lane to one thread); readers
// only read after the writer is quiet (documented above and enforced by the runners' APIs).
unsafe impl Sync for Lane {}

impl Lane {
    pub(crate) fn new(name: String, capacity: usize) -> Self {
        Lane {
            name,
            slots: (0..capacity).map(|_| UnsafeCell::new(EMPTY)).collect(),
            head: AtomicU64::new(0),
        }
    }

    /// Appends an event (single writer, wait-free, no allocation).
    pub(crate) fn push(&self, event: TraceEvent) {
        let cap = self.slots.len() as u64;
        if cap == 0 {
            return;
        }
        let head = self.head.load(Ordering::Relaxed);
        if let Some(slot) = self.slots.get((head % cap) as usize) {
            // SAFETY: only the lane's single writer writes slots.
            unsafe { *slot.get() = event };
        }
        self.head.store(head + 1, Ordering::Release);
    }

    fn events(&self) -> (Vec<TraceEvent>, u64) {
        let cap = self.slots.len() as u64;
        let head = self.head.load(Ordering::Acquire);
        let kept = head.min(cap);
        let mut out = Vec::with_capacity(kept as usize);
        for i in head - kept..head {
            if let Some(slot) = self.slots.get((i % cap) as usize) {
                // SAFETY: the writer is quiet while we export (see module docs).
                out.push(unsafe { *slot.get() });
            }
        }
        (out, head - kept)
    }
}

/// A finished trace: the lanes of a task set with the names of its tasks.
pub struct Trace<'a> {
    pub(crate) lanes: &'a [std::sync::Arc<Lane>],
    pub(crate) task_names: Vec<&'a str>,
}

fn push_json_str(out: &mut String, s: &str) {
    // Task and label names rarely need escaping: copy them whole then.
    if !s.bytes().any(|b| b == b'"' || b == b'\\' || b < 0x20) {
        out.push('"');
        out.push_str(s);
        out.push('"');
        return;
    }
    out.push('"');
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            c if (c as u32) < 0x20 => {
                let _ = write!(out, "\\u{:04x}", c as u32);
            }
            c => out.push(c),
        }
    }
    out.push('"');
}

/// Appends `n` in decimal (what `{}` writes, without the formatter's machinery: a trace has
/// hundreds of thousands of numbers).
fn push_u64(out: &mut String, mut n: u64) {
    let mut digits = [0u8; 20];
    let mut i = digits.len();
    loop {
        i -= 1;
        digits[i] = b'0' + (n % 10) as u8;
        n /= 10;
        if n == 0 {
            break;
        }
    }
    for &d in &digits[i..] {
        out.push(char::from(d));
    }
}

fn push_us(out: &mut String, ns: u64) {
    push_u64(out, ns / 1000);
    let frac = ns % 1000;
    out.push('.');
    out.push(char::from(b'0' + (frac / 100) as u8));
    out.push(char::from(b'0' + (frac / 10 % 10) as u8));
    out.push(char::from(b'0' + (frac % 10) as u8));
}

impl Trace<'_> {
    /// Events kept in all lanes.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn event_count(&self) -> usize {
        self.lanes.iter().map(|l| l.events().0.len()).sum()
    }

    /// Events overwritten because a lane was full.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn dropped(&self) -> u64 {
        self.lanes.iter().map(|l| l.events().1).sum()
    }

    /// The trace as Chrome trace-event JSON: one `tid` per lane, a complete event ("X") per
    /// body run, instant events for marks and faults; timestamps in microseconds with
    /// nanosecond digits. Deterministic: the same events give the same bytes.
    ///
    /// Real-time: no (allocates).
    pub fn to_chrome_json(&self) -> String {
        let mut out = String::with_capacity(256 + self.event_count() * 96);
        out.push_str("{\"displayTimeUnit\":\"ns\",\"traceEvents\":[\n");
        out.push_str(
            "{\"name\":\"process_name\",\"ph\":\"M\",\"pid\":1,\"tid\":0,\"args\":{\"name\":\"rtcnc executive\"}}",
        );
        for (lane_index, lane) in self.lanes.iter().enumerate() {
            let tid = lane_index + 1;
            out.push_str(",\n{\"name\":\"thread_name\",\"ph\":\"M\",\"pid\":1,\"tid\":");
            let _ = write!(out, "{tid}");
            out.push_str(",\"args\":{\"name\":");
            push_json_str(&mut out, &lane.name);
            out.push_str("}}");
            let _ = write!(
                out,
                ",\n{{\"name\":\"thread_sort_index\",\"ph\":\"M\",\"pid\":1,\"tid\":{tid},\"args\":{{\"sort_index\":{tid}}}}}"
            );
            let args = format!(",\"pid\":1,\"tid\":{tid},\"args\":{{\"task\":");
            let (events, _) = lane.events();
            for e in events {
                let task = self.task_names.get(e.task as usize).copied().unwrap_or("?");
                out.push_str(",\n{\"name\":");
                match e.kind {
                    EventKind::Span => {
                        push_json_str(&mut out, task);
                        out.push_str(",\"cat\":\"task\",\"ph\":\"X\",\"ts\":");
                        push_us(&mut out, e.time);
                        out.push_str(",\"dur\":");
                        push_us(&mut out, e.arg);
                    }
                    EventKind::Mark => {
                        push_json_str(&mut out, e.label);
                        out.push_str(",\"cat\":\"mark\",\"ph\":\"i\",\"s\":\"t\",\"ts\":");
                        push_us(&mut out, e.time);
                    }
                    EventKind::Fault => {
                        push_json_str(&mut out, e.label);
                        out.push_str(",\"cat\":\"fault\",\"ph\":\"i\",\"s\":\"g\",\"ts\":");
                        push_us(&mut out, e.time);
                    }
                }
                out.push_str(&args);
                push_json_str(&mut out, task);
                if e.kind != EventKind::Span {
                    out.push_str(",\"value\":");
                    push_u64(&mut out, e.arg);
                }
                out.push_str("}}");
            }
        }
        out.push_str("\n]}\n");
        out
    }

    /// Writes [`to_chrome_json`](Self::to_chrome_json) to `path`.
    ///
    /// Real-time: no (allocates, writes a file).
    pub fn write_chrome_json(&self, path: &std::path::Path) -> std::io::Result<()> {
        std::fs::write(path, self.to_chrome_json())
    }
}
