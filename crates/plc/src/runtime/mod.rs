//! A running instance of a compiled program: memory, I/O images, scans and faults;
//! `monitor` (variables by name, forcing), `signals` (the machine interface) and `retain`
//! (retained variables) add to it.

mod monitor;
mod retain;
mod signals;

use retain::retain_leaves;
pub use retain::{RetainReport, RetainSnapshot};

use std::path::Path;
use std::sync::Arc;
use std::time::Duration;

use crate::error::{Fault, FaultKind};
use crate::lexer::{AddrSize, Area, Tok};
use crate::program::{Program, Symbol};
use crate::signals::{ConfigError, Direction, PlcConfig, Signal, SignalKind};
use crate::types::{Elem, Repr, Type};
use crate::value::{Value, ValueError};
use crate::vm::{Flow, Vm};

/// Runtime settings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RuntimeOptions {
    /// Statements plus loop iterations one scan may execute before the watchdog stops
    /// the PLC. Counting work instead of time makes the watchdog deterministic. The
    /// default, 200 000, is a few milliseconds of work at ~15 ns per statement.
    pub watchdog_budget: u64,
    /// Most variables that can be forced at once (the force table is preallocated).
    pub max_forces: usize,
}

impl Default for RuntimeOptions {
    fn default() -> Self {
        RuntimeOptions {
            watchdog_budget: 1_000_000,
            max_forces: 64,
        }
    }
}

/// Restart kinds of IEC 61131-3.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Restart {
    /// All variables take their initial values.
    Cold,
    /// RETAIN variables keep their values, all others take their initial values.
    Warm,
}

/// Errors of on-line access by name.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum MonitorError {
    /// No such variable.
    #[error("no variable '{0}'")]
    Unknown(String),
    /// The name is not a variable path.
    #[error("'{0}' is not a variable path (name, name.member, name[index])")]
    BadPath(String),
    /// The variable is not elementary (array, structure, instance).
    #[error("'{0}' is not an elementary variable")]
    NotScalar(String),
    /// The value does not fit.
    #[error("{name}: {error}")]
    Value {
        /// Variable.
        name: String,
        /// Why.
        error: ValueError,
    },
    /// The force table is full.
    #[error("cannot force more than {0} variables")]
    ForceTableFull(usize),
    /// A short name matches variables in several program instances.
    #[error("'{0}' is ambiguous; prefix it with the program instance name")]
    Ambiguous(String),
}

impl MonitorError {
    /// Stable code.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn code(&self) -> &'static str {
        match self {
            MonitorError::Unknown(_) => "unknown-variable",
            MonitorError::BadPath(_) => "bad-path",
            MonitorError::NotScalar(_) => "not-scalar",
            MonitorError::Value { .. } => "bad-value",
            MonitorError::ForceTableFull(_) => "force-table-full",
            MonitorError::Ambiguous(_) => "ambiguous",
        }
    }
}

/// A resolved variable: address and type, for repeated access without name look-ups.
#[derive(Debug, Clone, PartialEq)]
pub struct VarRef {
    slot: u32,
    ty: Type,
    bit: Option<u8>,
    /// Written by the PLC's input image, a VAR_INPUT of the program, etc.: informative.
    located_input: bool,
}

impl VarRef {
    /// The variable's byte address in PLC memory (identifies it, as in
    /// [`Runtime::forced_slots`]).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn slot(&self) -> u32 {
        self.slot
    }
    /// The variable's type.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn ty(&self) -> &Type {
        &self.ty
    }
    /// True for a variable located in the input image: the next scan overwrites what
    /// [`Runtime::write`] put there, so commissioning forces it instead.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn is_located_input(&self) -> bool {
        self.located_input
    }
    /// The elementary type of a scalar variable (BOOL for a bit access).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn elem(&self) -> Option<Elem> {
        if self.bit.is_some() {
            Some(Elem::Bool)
        } else {
            self.ty.scalar()
        }
    }
}

/// A retained variable, as saved to and restored from the retain file.
#[derive(Debug, Clone)]
struct RetainLeaf {
    path: String,
    slot: u32,
    ty: Type,
}

/// A located variable's copy between its image and memory, with the image, byte offset
/// and representation worked out once rather than on every scan.
#[derive(Debug, Clone, Copy)]
struct ImageCopy {
    image: usize,
    offset: usize,
    size: AddrSize,
    bit: u8,
    elem: Elem,
    slot: usize,
    repr: Repr,
}

impl ImageCopy {
    /// The located variables of the areas `area` is not: copied in at scan start (all but
    /// the outputs) or out at scan end (all but the inputs), in declaration order.
    fn plan(program: &Program, skipped: Area) -> Box<[ImageCopy]> {
        program
            .located
            .iter()
            .filter(|l| l.at.area != skipped)
            .map(|l| ImageCopy {
                image: crate::program::area_index(l.at.area),
                offset: l.at.byte_offset(),
                size: l.at.size,
                bit: l.at.bit,
                elem: l.elem,
                slot: l.slot as usize,
                repr: Repr::of(l.elem),
            })
            .collect()
    }
}

/// One instance of a program: what the kernel's PLC task owns and calls every period.
#[derive(Debug)]
pub struct Runtime {
    program: Arc<Program>,
    vm: Vm,
    images: [Vec<u8>; 3],
    /// Located variables copied from their images at scan start.
    copied_in: Box<[ImageCopy]>,
    /// Located variables copied to their images at scan end.
    copied_out: Box<[ImageCopy]>,
    safe_outputs: Vec<u8>,
    forces: Vec<(u32, Repr, u64)>,
    options: RuntimeOptions,
    fault: Option<Fault>,
    scans: u64,
    /// AXIS_REF variables and the axis numbers they hold.
    axis_bindings: Vec<(u32, u64)>,
    next_due: Vec<Option<i64>>,
    /// Trigger values seen on the previous scan (event tasks).
    trigger_prev: Vec<bool>,
    signals: Vec<Option<(u32, Elem)>>,
    safe_slots: Vec<(u32, Repr, u64)>,
    retain: Arc<[RetainLeaf]>,
}

impl std::fmt::Debug for Vm {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Vm")
            .field("bytes", &self.mem.len())
            .finish()
    }
}

impl Runtime {
    /// Creates an instance with default options: memory at its initial values.
    ///
    /// Real-time: no (set-up: allocates).
    pub fn new(program: Arc<Program>) -> Runtime {
        Runtime::with_options(program, RuntimeOptions::default())
    }

    /// Creates an instance; all memory is allocated here, none during scans.
    ///
    /// Real-time: no (set-up: allocates).
    pub fn with_options(program: Arc<Program>, options: RuntimeOptions) -> Runtime {
        let sizes = program.image_sizes;
        let retain: Arc<[RetainLeaf]> = retain_leaves(&program).into();
        let n_tasks = program.tasks.len();
        Runtime {
            vm: Vm {
                mem: program.init.clone(),
                frame: 0,
                now: 0,
                budget: 0,
                fault: None,
                fault_at: None,
                axes: Vec::new(),
                pou: 0,
            },
            images: [vec![0; sizes[0]], vec![0; sizes[1]], vec![0; sizes[2]]],
            copied_in: ImageCopy::plan(&program, Area::Output),
            copied_out: ImageCopy::plan(&program, Area::Input),
            safe_outputs: vec![0; sizes[1]],
            forces: Vec::with_capacity(options.max_forces),
            options,
            fault: None,
            scans: 0,
            axis_bindings: Vec::new(),
            next_due: vec![None; n_tasks],
            trigger_prev: vec![false; n_tasks],
            signals: vec![None; Signal::ALL.len()],
            safe_slots: Vec::new(),
            retain,
            program,
        }
    }

    /// The program this instance runs.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn program(&self) -> &Arc<Program> {
        &self.program
    }

    /// Number of scans run since the start or the last restart.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn scan_count(&self) -> u64 {
        self.scans
    }

    /// State and set-point of the auxiliary axis bound to AXIS_REF variable `name` (as in
    /// the configuration's `[axes]`).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn axis(&self, name: &str) -> Option<crate::plcopen::AxisStatus> {
        self.vm
            .axes
            .iter()
            .find(|a| a.name == name)
            .map(|a| a.status())
    }

    /// The index of the auxiliary axis bound to AXIS_REF variable `name`, for
    /// [`axis_at`](Self::axis_at) and [`set_axis_drive`](Self::set_axis_drive).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn axis_index(&self, name: &str) -> Option<usize> {
        self.vm.axes.iter().position(|a| a.name == name)
    }

    /// State and set-point of auxiliary axis `index` ([`axis_index`](Self::axis_index)).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn axis_at(&self, index: usize) -> Option<crate::plcopen::AxisStatus> {
        self.vm.axes.get(index).map(|a| a.status())
    }

    /// Connects auxiliary axis `index` to a drive: its report of this period (position,
    /// enabled, faulted), given before the period's [`scan`](Self::scan) or
    /// [`advance_axes`](Self::advance_axes). From the first report on, MC_Power waits for
    /// the drive to be enabled, the actual position is the drive's, and a drive fault or
    /// drop-out is an axis error (ErrorStop, ErrorID 16#12).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn set_axis_drive(&mut self, index: usize, feedback: crate::plcopen::DriveFeedback) {
        if let Some(a) = self.vm.axes.get_mut(index) {
            a.set_drive(feedback);
        }
    }

    /// Advances every auxiliary axis's set-point to time `now` without running the
    /// programs: for a caller that scans less often than its drives take set-points (a
    /// scan at `now` afterwards does not move them again).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn advance_axes(&mut self, now: Duration) {
        let now = duration_ns(now);
        for a in self.vm.axes.iter_mut() {
            a.step(now);
        }
    }

    /// Every configured auxiliary axis: its AXIS_REF variable and status.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn axes(&self) -> impl Iterator<Item = (&str, crate::plcopen::AxisStatus)> {
        self.vm.axes.iter().map(|a| (a.name.as_str(), a.status()))
    }

    /// The fault that stopped the PLC, if any.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn fault(&self) -> Option<&Fault> {
        self.fault.as_ref()
    }

    /// Restarts after a fault or on request. Forces and the signal mapping stay.
    ///
    /// Real-time: no (allocates).
    pub fn restart(&mut self, kind: Restart) {
        for a in self.vm.axes.iter_mut() {
            a.reset();
        }
        let mut kept: Vec<(u32, Vec<u8>)> = Vec::new();
        if kind == Restart::Warm {
            for l in self.retain.iter() {
                let n = bytes_of(&l.ty);
                let s = l.slot as usize;
                if let Some(b) = self.vm.mem.get(s..s + n) {
                    kept.push((l.slot, b.to_vec()));
                }
            }
        }
        self.vm.mem.copy_from_slice(&self.program.init);
        for (slot, vals) in kept {
            let s = slot as usize;
            self.vm.mem[s..s + vals.len()].copy_from_slice(&vals);
        }
        self.fault = None;
        self.vm.fault = None;
        self.vm.fault_at = None;
        self.scans = 0;
        self.next_due.iter_mut().for_each(|d| *d = None);
        self.trigger_prev.iter_mut().for_each(|p| *p = false);
    }

    /// The input image (`%I`), written by the caller before a scan.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn input_image_mut(&mut self) -> &mut [u8] {
        &mut self.images[0]
    }
    /// The output image (`%Q`), valid after a scan (the safe image after a fault).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn output_image(&self) -> &[u8] {
        &self.images[1]
    }
    /// The marker image (`%M`).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn marker_image(&self) -> &[u8] {
        &self.images[2]
    }

    /// Runs one scan at PLC time `now` (time since the PLC started, from the caller's clock
    /// — virtual or real): reads the input image, runs every task that is due (tasks
    /// without INTERVAL run every scan, in priority order), writes the output image.
    /// After a fault the PLC stays stopped (outputs safe) until [`Runtime::restart`].
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn scan(&mut self, now: Duration) -> Result<(), Fault> {
        let now_ns = duration_ns(now);
        self.begin(now_ns)?;
        for t in 0..self.program.tasks.len() {
            let task = &self.program.tasks[t];
            let due = match (task.trigger_slot, task.interval, self.next_due[t]) {
                (Some(slot), _, _) => {
                    let now_set = self.vm.ld(slot as usize, Repr::Bool) != 0;
                    let rising = now_set && !self.trigger_prev[t];
                    self.trigger_prev[t] = now_set;
                    rising
                }
                (None, None, _) => true,
                (None, Some(_), None) => true,
                (None, Some(_), Some(d)) => now_ns >= d,
            };
            if due {
                if let Some(iv) = self.program.tasks[t].interval {
                    let iv = duration_ns(iv);
                    let mut next = self.next_due[t].unwrap_or(now_ns).saturating_add(iv);
                    if next <= now_ns {
                        // Overrun: skip the missed activations rather than run them in a burst.
                        next = now_ns.saturating_add(iv);
                    }
                    self.next_due[t] = Some(next);
                }
                self.run_task_programs(t)?;
            }
        }
        self.end();
        Ok(())
    }

    /// Whether a [`scan`](Self::scan) at `now` would run a task. False only when every task
    /// is cyclic with an INTERVAL that has not come round yet (and the PLC is not faulted):
    /// such a scan would only copy the images, so a caller that calls more often than the
    /// PLC's own intervals may skip it and keep the outputs of the last scan. Tasks without
    /// an interval, or started by a trigger variable, make every scan due.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn is_due(&self, now: Duration) -> bool {
        let now_ns = duration_ns(now);
        self.fault.is_some()
            || self
                .program
                .tasks
                .iter()
                .zip(&self.next_due)
                .any(|(task, next)| {
                    task.trigger_slot.is_some()
                        || task.interval.is_none()
                        || next.is_none_or(|d| now_ns >= d)
                })
    }

    /// Runs one activation of task `task` (index into [`Program::tasks`]) at time `now`,
    /// with its own input and output image transfer: for a kernel that puts each task of
    /// the CONFIGURATION on its own executive slot.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn run_task(&mut self, task: usize, now: Duration) -> Result<(), Fault> {
        self.begin(duration_ns(now))?;
        if task < self.program.tasks.len() {
            self.run_task_programs(task)?;
        }
        self.end();
        Ok(())
    }

    fn begin(&mut self, now: i64) -> Result<(), Fault> {
        if let Some(f) = &self.fault {
            return Err(f.clone());
        }
        self.scans += 1;
        self.vm.now = now;
        // The motion task: every axis to this scan's time before the programs command.
        for a in self.vm.axes.iter_mut() {
            a.step(now);
        }
        for &(slot, number) in &self.axis_bindings {
            self.vm.st(slot as usize, Repr::U32, number);
        }
        self.vm.budget = self.options.watchdog_budget.max(2);
        for l in self.copied_in.iter() {
            let v = self
                .images
                .get(l.image)
                .map_or(0, |img| read_image(img, l.size, l.offset, l.bit, l.elem));
            self.vm.st(l.slot, l.repr, v);
        }
        self.apply_forces();
        Ok(())
    }

    fn run_task_programs(&mut self, t: usize) -> Result<(), Fault> {
        let program = Arc::clone(&self.program);
        for &i in &program.tasks[t].program_ids {
            let inst = &program.instances[i];
            let flow = self.vm.run_program(&program.code, inst.pou, &inst.body);
            if flow == Flow::Fault || self.vm.fault.is_some() {
                return Err(self.stop());
            }
        }
        Ok(())
    }

    fn end(&mut self) {
        self.apply_forces();
        for l in self.copied_out.iter() {
            let v = self.vm.ld(l.slot, l.repr);
            if let Some(img) = self.images.get_mut(l.image) {
                write_image(img, l.size, l.offset, l.bit, l.elem, v);
            }
        }
    }

    fn apply_forces(&mut self) {
        for &(slot, r, v) in &self.forces {
            self.vm.st(slot as usize, r, v);
        }
    }

    /// Stops the PLC: outputs and signals from the PLC go to their safe values.
    #[cold]
    fn stop(&mut self) -> Fault {
        let kind = match self.vm.fault {
            Some(FaultKind::WatchdogExceeded { .. }) | None => FaultKind::WatchdogExceeded {
                budget: self.options.watchdog_budget,
            },
            Some(k) => k,
        };
        let (pou, line) = self.vm.fault_at.unwrap_or((0, 0));
        let name = self
            .program
            .pou_names
            .get(pou as usize)
            .cloned()
            .unwrap_or_else(|| Arc::from("?"));
        let fault = Fault {
            kind,
            pou: name,
            line: self.program.lines.locate(line).1,
            scan: self.scans,
        };
        self.images[1].copy_from_slice(&self.safe_outputs);
        for &(slot, r, v) in &self.safe_slots {
            self.vm.st(slot as usize, r, v);
        }
        self.fault = Some(fault.clone());
        fault
    }
}

/// Decodes the value of type `ty` stored at byte address `slot`.
fn value_at(mem: &[u8], slot: usize, ty: &Type) -> Value {
    match ty {
        Type::String(_) => {
            let mut buf = [0u8; crate::types::MAX_STRING_LEN as usize + 1];
            let n = crate::strings::read(mem, slot, false, &mut buf);
            Value::String(
                buf[..n]
                    .iter()
                    .map(|&b| crate::charset::decode(b))
                    .collect(),
            )
        }
        Type::WString(_) => {
            let mut buf = [0u16; crate::types::MAX_STRING_LEN as usize + 1];
            let n = crate::strings::read_units(mem, slot, true, &mut buf);
            Value::String(String::from_utf16_lossy(&buf[..n]))
        }
        t => {
            let e = t.scalar().unwrap_or(Elem::LWord);
            Value::from_slot(e, Repr::of(e).load(mem, slot))
        }
    }
}

fn duration_ns(d: Duration) -> i64 {
    i64::try_from(d.as_nanos()).unwrap_or(i64::MAX)
}

fn encode_f64(e: Elem, v: f64) -> u64 {
    match e {
        Elem::Bool => (v != 0.0) as u64,
        Elem::Real => ((v as f32) as f64).to_bits(),
        Elem::LReal => v.to_bits(),
        Elem::Time => (v * 1e6).round() as i64 as u64,
        e => {
            let k = e.int_kind().unwrap_or(crate::types::IntKind::I64);
            let (lo, hi) = k.range_f64();
            let x = v.round().clamp(lo, hi);
            k.wrap(if k.signed() {
                x as i64 as u64
            } else {
                x as u64
            })
        }
    }
}

fn decode_f64(e: Elem, v: u64) -> f64 {
    match e {
        Elem::Bool => (v & 1) as f64,
        Elem::Real | Elem::LReal => f64::from_bits(v),
        Elem::Time => v as i64 as f64 / 1e6,
        e if e.int_kind().is_some_and(|k| k.signed()) => v as i64 as f64,
        _ => v as f64,
    }
}

fn read_image(img: &[u8], size: AddrSize, off: usize, bit: u8, e: Elem) -> u64 {
    let mut b = [0u8; 8];
    let n = match size {
        AddrSize::Bit => return img.get(off).map_or(0, |x| ((x >> bit) & 1) as u64),
        AddrSize::Byte => 1,
        AddrSize::Word => 2,
        AddrSize::Double => 4,
        AddrSize::Long => 8,
    };
    if let Some(src) = img.get(off..off + n) {
        b[..n].copy_from_slice(src);
    }
    let raw = u64::from_le_bytes(b);
    match e {
        Elem::Real => (f32::from_bits(raw as u32) as f64).to_bits(),
        e => e.int_kind().map_or(raw, |k| k.wrap(raw)),
    }
}

fn write_image(img: &mut [u8], size: AddrSize, off: usize, bit: u8, e: Elem, v: u64) {
    let n = match size {
        AddrSize::Bit => {
            if let Some(x) = img.get_mut(off) {
                *x = (*x & !(1 << bit)) | (((v & 1) as u8) << bit);
            }
            return;
        }
        AddrSize::Byte => 1,
        AddrSize::Word => 2,
        AddrSize::Double => 4,
        AddrSize::Long => 8,
    };
    let raw = if e == Elem::Real {
        (f64::from_bits(v) as f32).to_bits() as u64
    } else {
        v
    };
    if let Some(dst) = img.get_mut(off..off + n) {
        dst.copy_from_slice(&raw.to_le_bytes()[..n]);
    }
}

/// The representation of a scalar type in memory.
fn repr_of(t: &Type) -> Repr {
    t.repr().unwrap_or(Repr::U64)
}

/// Bytes of a retained leaf (an elementary value or a string).
fn bytes_of(t: &Type) -> usize {
    match t {
        Type::String(n) => crate::types::string_bytes(*n) as usize,
        Type::WString(n) => crate::types::wstring_bytes(*n) as usize,
        t => t.scalar().map_or(8, Elem::size) as usize,
    }
}
