//! The machine interface: mapping signals onto variables, safe values, signal access.

use super::*;

impl Runtime {
    /// Applies a machine configuration: maps signals onto variables and sets safe values.
    ///
    /// Real-time: no (set-up: allocates).
    pub fn configure(&mut self, cfg: &PlcConfig) -> Result<(), ConfigError> {
        let mut signals = vec![None; Signal::ALL.len()];
        let mut safe_slots: Vec<(u32, Repr, u64)> = Vec::new();
        for (sname, var) in &cfg.signals {
            let sig = Signal::from_name(sname)
                .ok_or_else(|| ConfigError::UnknownSignal(sname.clone()))?;
            let r = self.resolve(var).map_err(|error| ConfigError::Variable {
                signal: sname.clone(),
                error,
            })?;
            let e = r.elem().filter(|_| r.bit.is_none());
            // BOOL and TIME are integer-like inside, but neither holds a number: a speed
            // in a BOOL would read as 0 or 1, in a TIME as nanoseconds.
            let ok = match (sig.kind(), e) {
                (SignalKind::Bool, Some(Elem::Bool)) => true,
                (_, Some(Elem::Bool | Elem::Time)) => false,
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
                safe_slots.push((r.slot, Repr::of(e), encode_f64(e, sig.safe_value())));
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
            } else if let Some(s) = safe_slots.iter_mut().find(|(s, ..)| *s == r.slot) {
                s.2 = v;
            } else {
                return Err(bad(
                    "is neither a %Q variable nor mapped to a signal from the PLC".into(),
                ));
            }
        }
        let mut axes = Vec::with_capacity(cfg.axes.len());
        let mut bindings = Vec::with_capacity(cfg.axes.len());
        for (var, axis) in &cfg.axes {
            let bad = |message: String| ConfigError::Axis {
                variable: var.clone(),
                message,
            };
            let r = self.resolve(var).map_err(|e| bad(e.to_string()))?;
            if r.elem() != Some(Elem::UDInt) || r.bit.is_some() {
                return Err(bad(format!(
                    "is {}, not an AXIS_REF",
                    self.program.type_name(&r.ty)
                )));
            }
            let a = crate::plcopen::Axis::new(var, *axis).map_err(bad)?;
            axes.push(a);
            bindings.push((r.slot, axes.len() as u64));
        }
        self.signals = signals;
        self.safe_slots = safe_slots;
        self.safe_outputs = safe_outputs;
        self.vm.axes = axes;
        self.axis_bindings = bindings;
        Ok(())
    }

    /// True if the signal is mapped to a variable.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn has_signal(&self, s: Signal) -> bool {
        self.signals.get(s as usize).is_some_and(|x| x.is_some())
    }

    /// Sets a signal to the PLC (ignored when unmapped or not `ToPlc`). Numbers are
    /// converted to the variable's type (rounded for integers).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn set_signal(&mut self, s: Signal, value: f64) {
        if s.direction() != Direction::ToPlc {
            return;
        }
        if let Some(Some((slot, e))) = self.signals.get(s as usize).copied() {
            self.vm.st(slot as usize, Repr::of(e), encode_f64(e, value));
        }
    }

    /// Sets a BOOL signal to the PLC.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn set_signal_bool(&mut self, s: Signal, value: bool) {
        self.set_signal(s, if value { 1.0 } else { 0.0 });
    }

    /// Reads a signal (either direction) as a number (BOOL as 0/1); `None` when unmapped.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn signal(&self, s: Signal) -> Option<f64> {
        let (slot, e) = self.signals.get(s as usize).copied().flatten()?;
        let v = self.vm.ld(slot as usize, Repr::of(e));
        Some(decode_f64(e, v))
    }

    /// Reads a BOOL signal; unmapped signals read as their safe value.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn signal_bool(&self, s: Signal) -> bool {
        self.signal(s).unwrap_or(s.safe_value()) != 0.0
    }
}
