//! A running instance of a compiled program: memory, I/O images, scans, faults, on-line
//! monitoring and forcing, machine-interface signals and retained variables.

use std::fs;
use std::io::Write as _;
use std::path::Path;
use std::sync::Arc;
use std::time::Duration;

use crate::ast::VarKind;
use crate::error::{Fault, FaultKind};
use crate::lexer::{AddrSize, Area, Tok};
use crate::program::{Program, Symbol};
use crate::signals::{ConfigError, Direction, PlcConfig, Signal, SignalKind};
use crate::types::{Elem, Type, string_slots};
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
    /// The slot index in PLC memory.
    pub fn slot(&self) -> u32 {
        self.slot
    }
    /// The variable's type.
    pub fn ty(&self) -> &Type {
        &self.ty
    }
    /// The elementary type of a scalar variable (BOOL for a bit access).
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

/// One instance of a program: what the kernel's PLC task owns and calls every period.
#[derive(Debug)]
pub struct Runtime {
    program: Arc<Program>,
    vm: Vm,
    images: [Vec<u8>; 3],
    safe_outputs: Vec<u8>,
    forces: Vec<(u32, u64)>,
    options: RuntimeOptions,
    fault: Option<Fault>,
    scans: u64,
    next_due: Vec<Option<i64>>,
    signals: Vec<Option<(u32, Elem)>>,
    safe_slots: Vec<(u32, u64)>,
    retain: Vec<RetainLeaf>,
}

impl std::fmt::Debug for Vm {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Vm")
            .field("slots", &self.mem.len())
            .finish()
    }
}

impl Runtime {
    /// Creates an instance with default options: memory at its initial values.
    pub fn new(program: Arc<Program>) -> Runtime {
        Runtime::with_options(program, RuntimeOptions::default())
    }

    /// Creates an instance; all memory is allocated here, none during scans.
    pub fn with_options(program: Arc<Program>, options: RuntimeOptions) -> Runtime {
        let sizes = program.image_sizes;
        let retain = retain_leaves(&program);
        let n_tasks = program.tasks.len();
        Runtime {
            vm: Vm {
                mem: program.init.clone(),
                frame: 0,
                now: 0,
                budget: 0,
                fault: None,
                fault_at: None,
                pou: 0,
            },
            images: [vec![0; sizes[0]], vec![0; sizes[1]], vec![0; sizes[2]]],
            safe_outputs: vec![0; sizes[1]],
            forces: Vec::with_capacity(options.max_forces),
            options,
            fault: None,
            scans: 0,
            next_due: vec![None; n_tasks],
            signals: vec![None; Signal::ALL.len()],
            safe_slots: Vec::new(),
            retain,
            program,
        }
    }

    /// The program this instance runs.
    pub fn program(&self) -> &Arc<Program> {
        &self.program
    }

    /// Number of scans run since the start or the last restart.
    pub fn scan_count(&self) -> u64 {
        self.scans
    }

    /// The fault that stopped the PLC, if any.
    pub fn fault(&self) -> Option<&Fault> {
        self.fault.as_ref()
    }

    /// Restarts after a fault or on request. Forces and the signal mapping stay.
    pub fn restart(&mut self, kind: Restart) {
        let mut kept: Vec<(u32, Vec<u64>)> = Vec::new();
        if kind == Restart::Warm {
            for l in &self.retain {
                let n = slots_of(&l.ty) as usize;
                let s = l.slot as usize;
                kept.push((l.slot, self.vm.mem[s..s + n].to_vec()));
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
    }

    /// The input image (`%I`), written by the caller before a scan.
    pub fn input_image_mut(&mut self) -> &mut [u8] {
        &mut self.images[0]
    }
    /// The output image (`%Q`), valid after a scan (the safe image after a fault).
    pub fn output_image(&self) -> &[u8] {
        &self.images[1]
    }
    /// The marker image (`%M`).
    pub fn marker_image(&self) -> &[u8] {
        &self.images[2]
    }

    /// Runs one scan at PLC time `now` (time since the PLC started, from the caller's clock
    /// — virtual or real): reads the input image, runs every task that is due (tasks
    /// without INTERVAL run every scan, in priority order), writes the output image.
    /// After a fault the PLC stays stopped (outputs safe) until [`Runtime::restart`].
    pub fn scan(&mut self, now: Duration) -> Result<(), Fault> {
        let now_ns = duration_ns(now);
        self.begin(now_ns)?;
        for t in 0..self.program.tasks.len() {
            let due = match (self.program.tasks[t].interval, self.next_due[t]) {
                (None, _) => true,
                (Some(_), None) => true,
                (Some(_), Some(d)) => now_ns >= d,
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

    /// Runs one activation of task `task` (index into [`Program::tasks`]) at time `now`,
    /// with its own input and output image transfer: for a kernel that puts each task of
    /// the CONFIGURATION on its own executive slot.
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
        self.vm.budget = self.options.watchdog_budget.max(2);
        let program = &self.program;
        for l in program.located.iter() {
            if l.at.area == Area::Output {
                continue;
            }
            let img = &self.images[crate::program::area_index(l.at.area)];
            let v = read_image(img, l.at.size, l.at.byte_offset(), l.at.bit, l.elem);
            if let Some(s) = self.vm.mem.get_mut(l.slot as usize) {
                *s = v;
            }
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
        let program = &self.program;
        for l in program.located.iter() {
            if l.at.area == Area::Input {
                continue;
            }
            let v = self.vm.mem.get(l.slot as usize).copied().unwrap_or(0);
            let img = &mut self.images[crate::program::area_index(l.at.area)];
            write_image(img, l.at.size, l.at.byte_offset(), l.at.bit, l.elem, v);
        }
    }

    fn apply_forces(&mut self) {
        for &(slot, v) in &self.forces {
            if let Some(s) = self.vm.mem.get_mut(slot as usize) {
                *s = v;
            }
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
            line,
            scan: self.scans,
        };
        self.images[1].copy_from_slice(&self.safe_outputs);
        for &(slot, v) in &self.safe_slots {
            if let Some(s) = self.vm.mem.get_mut(slot as usize) {
                *s = v;
            }
        }
        self.fault = Some(fault.clone());
        fault
    }

    // ------------------------------------------------------------------ monitoring

    /// Resolves a variable path: `GLOBAL`, `INSTANCE.VAR`, `VAR` (searched in every program
    /// instance when not a global), members `timer.ET`, `axis[2].pos`, bits `word.3`.
    pub fn resolve(&self, path: &str) -> Result<VarRef, MonitorError> {
        resolve(&self.program, path)
    }

    /// Reads a scalar variable.
    pub fn read(&self, var: &VarRef) -> Value {
        let v = self.vm.mem.get(var.slot as usize).copied().unwrap_or(0);
        if let Some(b) = var.bit {
            return Value::Bool((v >> b) & 1 != 0);
        }
        match &var.ty {
            Type::String(_) => {
                let mut buf = [0u8; crate::types::MAX_STRING_LEN as usize + 1];
                let n = crate::strings::read(&self.vm.mem, var.slot as usize, &mut buf);
                Value::String(String::from_utf8_lossy(&buf[..n]).into_owned())
            }
            t => Value::from_slot(t.scalar().unwrap_or(Elem::LWord), v),
        }
    }

    /// Reads a variable by path.
    pub fn read_name(&self, path: &str) -> Result<Value, MonitorError> {
        let r = self.resolve(path)?;
        if r.elem().is_none() && !matches!(r.ty, Type::String(_)) {
            return Err(MonitorError::NotScalar(path.to_string()));
        }
        Ok(self.read(&r))
    }

    /// Formats a variable for display (enumerations by value name).
    pub fn format(&self, var: &VarRef) -> String {
        if let (Type::Enum(id), None) = (&var.ty, var.bit) {
            let v = self.vm.mem.get(var.slot as usize).copied().unwrap_or(0) as i64;
            if let Some(e) = self.program.enums.get(*id as usize) {
                if let Some((n, _)) = e.values.iter().find(|(_, x)| *x == v) {
                    return n.clone();
                }
            }
        }
        self.read(var).to_string()
    }

    /// Writes a scalar (or STRING) variable now; the next scan sees the value.
    pub fn write(&mut self, var: &VarRef, value: &Value) -> Result<(), ValueError> {
        let v = self.encode(var, value)?;
        self.put(var, v, value);
        Ok(())
    }

    fn encode(&self, var: &VarRef, value: &Value) -> Result<u64, ValueError> {
        match (&var.ty, var.bit) {
            (_, Some(_)) => Value::to_slot(value, Elem::Bool, None),
            (Type::String(_), None) => match value {
                Value::String(_) => Ok(0),
                _ => Err(ValueError::Kind {
                    given: "non-STRING",
                    ty: "STRING".into(),
                }),
            },
            (Type::Enum(id), None) => {
                let v = match value {
                    Value::Int(v) => *v,
                    Value::UInt(v) => *v as i64,
                    _ => {
                        return Err(ValueError::Kind {
                            given: "non-integer",
                            ty: "enumeration".into(),
                        });
                    }
                };
                let ok = self
                    .program
                    .enums
                    .get(*id as usize)
                    .is_some_and(|e| e.values.iter().any(|(_, x)| *x == v));
                if ok {
                    Ok(v as u64)
                } else {
                    Err(ValueError::Range {
                        value: v.to_string(),
                        ty: "enumeration".into(),
                    })
                }
            }
            (Type::Subrange(e, l, h), None) => value.to_slot(*e, Some((*l, *h))),
            (t, None) => match t.scalar() {
                Some(e) => value.to_slot(e, None),
                None => Err(ValueError::Kind {
                    given: "elementary",
                    ty: self.program.type_name(t),
                }),
            },
        }
    }

    fn put(&mut self, var: &VarRef, v: u64, value: &Value) {
        let slot = var.slot as usize;
        match (&var.ty, var.bit, value) {
            (_, Some(b), _) => {
                if let Some(s) = self.vm.mem.get_mut(slot) {
                    *s = (*s & !(1 << b)) | ((v & 1) << b);
                }
            }
            (Type::String(cap), None, Value::String(text)) => {
                crate::strings::write(&mut self.vm.mem, slot, *cap, text.as_bytes())
            }
            _ => {
                if let Some(s) = self.vm.mem.get_mut(slot) {
                    *s = v;
                }
            }
        }
    }

    /// Parses IEC text (`TRUE`, `42`, `2.5`, `T#20ms`, an enumeration value name) for a
    /// variable.
    pub fn parse_value(&self, var: &VarRef, text: &str) -> Result<Value, ValueError> {
        match (&var.ty, var.bit) {
            (_, Some(_)) => Value::parse(text, Elem::Bool),
            (Type::String(_), None) => {
                let t = text.trim();
                let t = t
                    .strip_prefix('\'')
                    .and_then(|x| x.strip_suffix('\''))
                    .unwrap_or(t);
                Ok(Value::String(t.to_string()))
            }
            (Type::Enum(id), None) => {
                let up = text.trim().to_ascii_uppercase();
                let name = up.rsplit('#').next().unwrap_or(&up);
                let e = self.program.enums.get(*id as usize);
                match e.and_then(|e| e.values.iter().find(|(n, _)| n == name)) {
                    Some((_, v)) => Ok(Value::Int(*v)),
                    None => Value::parse(text, Elem::DInt),
                }
            }
            (t, None) => match t.scalar() {
                Some(e) => Value::parse(text, e),
                None => Err(ValueError::Kind {
                    given: "text",
                    ty: self.program.type_name(t),
                }),
            },
        }
    }

    /// Forces a scalar variable: it holds `value` at the start and at the end of every
    /// scan (so a forced input is what the program reads, a forced output is what the
    /// output image gets) until unforced.
    pub fn force(&mut self, var: &VarRef, value: &Value) -> Result<(), MonitorError> {
        // Error texts are built only on error: forcing itself does not allocate.
        let name = || format!("slot {}", var.slot);
        if var.bit.is_some() || var.elem().is_none() {
            return Err(MonitorError::NotScalar(name()));
        }
        let v = self
            .encode(var, value)
            .map_err(|error| MonitorError::Value {
                name: name(),
                error,
            })?;
        match self.forces.iter_mut().find(|(s, _)| *s == var.slot) {
            Some(f) => f.1 = v,
            None => {
                if self.forces.len() >= self.options.max_forces {
                    return Err(MonitorError::ForceTableFull(self.options.max_forces));
                }
                self.forces.push((var.slot, v));
            }
        }
        self.put(var, v, value);
        Ok(())
    }

    /// Releases a forced variable; it keeps its value until the program or the input
    /// image changes it.
    pub fn unforce(&mut self, var: &VarRef) {
        self.forces.retain(|(s, _)| *s != var.slot);
    }

    /// Releases every force.
    pub fn unforce_all(&mut self) {
        self.forces.clear();
    }

    /// Slots currently forced.
    pub fn forced_slots(&self) -> impl Iterator<Item = u32> + '_ {
        self.forces.iter().map(|(s, _)| *s)
    }

    // ------------------------------------------------------------------ signals

    /// Applies a machine configuration: maps signals onto variables and sets safe values.
    pub fn configure(&mut self, cfg: &PlcConfig) -> Result<(), ConfigError> {
        let mut signals = vec![None; Signal::ALL.len()];
        let mut safe_slots: Vec<(u32, u64)> = Vec::new();
        for (sname, var) in &cfg.signals {
            let sig = Signal::from_name(sname)
                .ok_or_else(|| ConfigError::UnknownSignal(sname.clone()))?;
            let r = self.resolve(var).map_err(|error| ConfigError::Variable {
                signal: sname.clone(),
                error,
            })?;
            let e = r.elem().filter(|_| r.bit.is_none());
            let ok = match (sig.kind(), e) {
                (SignalKind::Bool, Some(Elem::Bool)) => true,
                (SignalKind::Number, Some(e)) => e.is_num(),
                (SignalKind::Integer, Some(e)) => e.is_int() || e.is_bit(),
                (SignalKind::Mask, Some(e)) => {
                    e.is_bit() || (e.is_int() && !e.int_kind().is_some_and(|k| k.signed()))
                }
                _ => false,
            };
            let Some(e) = e.filter(|_| ok) else {
                return Err(ConfigError::Type {
                    signal: sname.clone(),
                    kind: sig.kind(),
                    variable: var.clone(),
                    ty: self.program.type_name(&r.ty),
                });
            };
            signals[sig as usize] = Some((r.slot, e));
            if sig.direction() == Direction::FromPlc {
                safe_slots.push((r.slot, encode_f64(e, sig.safe_value())));
            }
        }
        let mut safe_outputs = vec![0u8; self.images[1].len()];
        for (var, text) in &cfg.safe_values {
            let bad = |message: String| ConfigError::SafeValue {
                variable: var.clone(),
                message,
            };
            let r = self.resolve(var).map_err(|e| bad(e.to_string()))?;
            let value = self.parse_value(&r, text).map_err(|e| bad(e.to_string()))?;
            let v = self.encode(&r, &value).map_err(|e| bad(e.to_string()))?;
            let located = self
                .program
                .located
                .iter()
                .find(|l| l.slot == r.slot && l.at.area == Area::Output);
            if let Some(l) = located {
                write_image(
                    &mut safe_outputs,
                    l.at.size,
                    l.at.byte_offset(),
                    l.at.bit,
                    l.elem,
                    v,
                );
            } else if let Some(s) = safe_slots.iter_mut().find(|(s, _)| *s == r.slot) {
                s.1 = v;
            } else {
                return Err(bad(
                    "is neither a %Q variable nor mapped to a signal from the PLC".into(),
                ));
            }
        }
        self.signals = signals;
        self.safe_slots = safe_slots;
        self.safe_outputs = safe_outputs;
        Ok(())
    }

    /// True if the signal is mapped to a variable.
    pub fn has_signal(&self, s: Signal) -> bool {
        self.signals.get(s as usize).is_some_and(|x| x.is_some())
    }

    /// Sets a signal to the PLC (ignored when unmapped or not `ToPlc`). Numbers are
    /// converted to the variable's type (rounded for integers).
    pub fn set_signal(&mut self, s: Signal, value: f64) {
        if s.direction() != Direction::ToPlc {
            return;
        }
        if let Some(Some((slot, e))) = self.signals.get(s as usize).copied() {
            if let Some(m) = self.vm.mem.get_mut(slot as usize) {
                *m = encode_f64(e, value);
            }
        }
    }

    /// Sets a BOOL signal to the PLC.
    pub fn set_signal_bool(&mut self, s: Signal, value: bool) {
        self.set_signal(s, if value { 1.0 } else { 0.0 });
    }

    /// Reads a signal (either direction) as a number (BOOL as 0/1); `None` when unmapped.
    pub fn signal(&self, s: Signal) -> Option<f64> {
        let (slot, e) = self.signals.get(s as usize).copied().flatten()?;
        let v = self.vm.mem.get(slot as usize).copied().unwrap_or(0);
        Some(decode_f64(e, v))
    }

    /// Reads a BOOL signal; unmapped signals read as their safe value.
    pub fn signal_bool(&self, s: Signal) -> bool {
        self.signal(s).unwrap_or(s.safe_value()) != 0.0
    }

    // ------------------------------------------------------------------ retain

    /// Writes the RETAIN variables to `path` atomically: a temporary file in the same
    /// directory, fsync, rename over the old file, fsync of the directory. A crash leaves
    /// either the old or the new file, never a torn one.
    pub fn save_retain(&self, path: &Path) -> std::io::Result<()> {
        let mut text = String::from("# rtcnc-plc retained variables v1\n");
        for l in &self.retain {
            let r = VarRef {
                slot: l.slot,
                ty: l.ty.clone(),
                bit: None,
                located_input: false,
            };
            let v = self.read(&r);
            let shown = match &v {
                Value::String(s) => format!(
                    "'{}'",
                    s.replace('$', "$$").replace('\'', "$'").replace('\n', "$N")
                ),
                Value::Real(x) => format!("{x:?}"),
                v => v.to_string(),
            };
            text.push_str(&format!("{} = {}\n", l.path, shown));
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

    /// Restores RETAIN variables from `path`. Entries whose name no longer exists or whose
    /// value no longer fits are skipped and counted; a missing file restores nothing.
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
            let parsed = if let Type::String(_) = r.ty {
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

/// What [`Runtime::load_retain`] did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RetainReport {
    /// Values restored.
    pub restored: usize,
    /// Entries skipped (unknown name or value that does not fit).
    pub skipped: usize,
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
            let (lo, hi) = k.range();
            let x = v.round().clamp(lo as f64, hi as f64);
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

fn slots_of(t: &Type) -> u32 {
    match t {
        Type::String(n) => string_slots(*n),
        _ => 1,
    }
}

fn member_symbols(p: &Program, ty: &Type) -> Option<Vec<Symbol>> {
    match ty {
        Type::Struct(id) => p.structs.get(*id as usize).map(|s| {
            s.fields
                .iter()
                .map(|f| Symbol {
                    name: f.name.clone(),
                    ty: f.ty.clone(),
                    addr: f.offset,
                    kind: VarKind::Local,
                    retain: false,
                    indirect: false,
                })
                .collect()
        }),
        Type::Fb(id) => p.fbs.get(*id as usize).map(|f| f.members.clone()),
        _ => None,
    }
}

fn retain_leaves(p: &Program) -> Vec<RetainLeaf> {
    fn walk(
        p: &Program,
        path: String,
        ty: &Type,
        slot: u32,
        retained: bool,
        out: &mut Vec<RetainLeaf>,
    ) {
        match ty {
            Type::Array(a) => {
                let mut idx: Vec<i64> = a.dims.iter().map(|(l, _)| *l).collect();
                for k in 0..a.len() {
                    let label: Vec<String> = idx.iter().map(|i| i.to_string()).collect();
                    walk(
                        p,
                        format!("{path}[{}]", label.join(",")),
                        &a.elem,
                        slot + k as u32 * a.elem_size,
                        retained,
                        out,
                    );
                    for d in (0..idx.len()).rev() {
                        idx[d] += 1;
                        if idx[d] <= a.dims[d].1 {
                            break;
                        }
                        idx[d] = a.dims[d].0;
                    }
                }
            }
            Type::Struct(_) | Type::Fb(_) => {
                for m in member_symbols(p, ty).unwrap_or_default() {
                    if m.indirect || m.kind == VarKind::Temp {
                        continue;
                    }
                    walk(
                        p,
                        format!("{path}.{}", m.name),
                        &m.ty,
                        slot + m.addr,
                        retained || m.retain,
                        out,
                    );
                }
            }
            t => {
                if retained {
                    out.push(RetainLeaf {
                        path,
                        slot,
                        ty: t.clone(),
                    });
                }
            }
        }
    }
    let mut out = Vec::new();
    for g in &p.globals {
        walk(p, g.name.clone(), &g.ty, g.addr, g.retain, &mut out);
    }
    for i in &p.instances {
        for v in &i.vars {
            walk(
                p,
                format!("{}.{}", i.name, v.name),
                &v.ty,
                v.addr,
                v.retain,
                &mut out,
            );
        }
    }
    out
}

fn resolve(p: &Program, path: &str) -> Result<VarRef, MonitorError> {
    let bad = || MonitorError::BadPath(path.to_string());
    let toks = crate::lexer::tokenize(path, "").map_err(|_| bad())?;
    let mut names: Vec<&Tok> = toks.iter().map(|t| &t.kind).collect();
    names.pop(); // Eof
    let mut it = names.into_iter().peekable();
    let first = match it.next() {
        Some(Tok::Ident(s)) => s.clone(),
        Some(Tok::Direct(d)) => d.to_string(),
        _ => return Err(bad()),
    };
    // Root: a global, an INSTANCE.VAR, or a variable of the one instance that has it.
    let mut cur: Option<(Type, u32)> = p
        .globals
        .iter()
        .find(|g| g.name == first)
        .map(|g| (g.ty.clone(), g.addr));
    if cur.is_none() {
        // `Instance.var` when the instance has that variable, else a variable of the one
        // instance that declares `first` (a variable may share its program's name).
        let second = match (it.clone().next(), it.clone().nth(1)) {
            (Some(Tok::Dot), Some(Tok::Ident(v))) => Some(v.clone()),
            _ => None,
        };
        let qualified = second.as_ref().and_then(|v| {
            p.instances
                .iter()
                .find(|i| i.name == first)
                .and_then(|i| i.vars.iter().find(|s| &s.name == v))
        });
        if let Some(s) = qualified {
            it.next();
            it.next();
            cur = Some((s.ty.clone(), s.addr));
        } else {
            let hits: Vec<&Symbol> = p
                .instances
                .iter()
                .filter_map(|i| i.vars.iter().find(|s| s.name == first))
                .collect();
            match hits.len() {
                0 => return Err(MonitorError::Unknown(path.to_string())),
                1 => cur = Some((hits[0].ty.clone(), hits[0].addr)),
                _ => return Err(MonitorError::Ambiguous(path.to_string())),
            }
        }
    }
    let (mut ty, mut slot) = cur.ok_or_else(|| MonitorError::Unknown(path.to_string()))?;
    let mut bit = None;
    while let Some(t) = it.next() {
        if bit.is_some() {
            return Err(bad());
        }
        match t {
            Tok::Dot => match it.next() {
                Some(Tok::Ident(m)) => {
                    let members = member_symbols(p, &ty).ok_or_else(bad)?;
                    let s = members
                        .iter()
                        .find(|s| &s.name == m)
                        .ok_or_else(|| MonitorError::Unknown(path.to_string()))?;
                    if s.indirect {
                        return Err(MonitorError::NotScalar(path.to_string()));
                    }
                    slot += s.addr;
                    ty = s.ty.clone();
                }
                Some(Tok::Int(b)) => {
                    let e = ty
                        .elem()
                        .filter(|e| e.int_kind().is_some() && *e != Elem::Bool)
                        .ok_or_else(bad)?;
                    if *b >= e.bits() as u128 {
                        return Err(bad());
                    }
                    bit = Some(*b as u8);
                }
                _ => return Err(bad()),
            },
            Tok::LBracket => {
                let Type::Array(a) = ty.clone() else {
                    return Err(bad());
                };
                let mut flat: u64 = 0;
                for (d, (lo, hi)) in a.dims.iter().enumerate() {
                    let neg = it.peek() == Some(&&Tok::Minus);
                    if neg {
                        it.next();
                    }
                    let Some(Tok::Int(v)) = it.next() else {
                        return Err(bad());
                    };
                    let i = if neg { -(*v as i128) } else { *v as i128 };
                    if i < *lo as i128 || i > *hi as i128 {
                        return Err(MonitorError::Unknown(path.to_string()));
                    }
                    flat = flat * (hi - lo + 1) as u64 + (i - *lo as i128) as u64;
                    let sep = it.next();
                    let last = d + 1 == a.dims.len();
                    if (last && sep != Some(&Tok::RBracket)) || (!last && sep != Some(&Tok::Comma))
                    {
                        return Err(bad());
                    }
                }
                slot += flat as u32 * a.elem_size;
                ty = a.elem.clone();
            }
            _ => return Err(bad()),
        }
    }
    let located_input = p
        .located
        .iter()
        .any(|l| l.slot == slot && l.at.area == Area::Input);
    Ok(VarRef {
        slot,
        ty,
        bit,
        located_input,
    })
}
