//! On-line monitoring: variables by path, reading, writing, forcing.

use super::*;

impl Runtime {
    /// Resolves a variable path: `GLOBAL`, `INSTANCE.VAR`, `VAR` (searched in every program
    /// instance when not a global), members `timer.ET`, `axis[2].pos`, bits `word.3`.
    ///
    /// Real-time: no (allocates).
    pub fn resolve(&self, path: &str) -> Result<VarRef, MonitorError> {
        resolve(&self.program, path)
    }

    /// Reads a scalar variable.
    ///
    /// Real-time: yes for a variable of elementary type (no allocation, no blocking); a
    /// `STRING` value allocates.
    pub fn read(&self, var: &VarRef) -> Value {
        if let Some(b) = var.bit {
            let v = self.vm.ld(var.slot as usize, repr_of(&var.ty));
            return Value::Bool((v >> b) & 1 != 0);
        }
        value_at(&self.vm.mem, var.slot as usize, &var.ty)
    }

    /// Reads a variable by path.
    ///
    /// Real-time: no (allocates).
    pub fn read_name(&self, path: &str) -> Result<Value, MonitorError> {
        let r = self.resolve(path)?;
        if r.elem().is_none() && !r.ty.is_string() {
            return Err(MonitorError::NotScalar(path.to_string()));
        }
        Ok(self.read(&r))
    }

    /// Formats a variable for display (enumerations by value name).
    ///
    /// Real-time: no (allocates).
    pub fn format(&self, var: &VarRef) -> String {
        if let (Type::Enum(id), None) = (&var.ty, var.bit) {
            let v = self.vm.ld(var.slot as usize, repr_of(&var.ty)) as i64;
            if let Some(e) = self.program.enums.get(*id as usize) {
                if let Some((n, _)) = e.values.iter().find(|(_, x)| *x == v) {
                    return n.clone();
                }
            }
        }
        self.read(var).to_string()
    }

    /// Writes a scalar (or STRING) variable now; the next scan sees the value (except a
    /// located input, which the input image overwrites: force it instead).
    ///
    /// Real-time: yes for a variable of elementary type (no allocation, no blocking); a
    /// `STRING` value or a refusal's message allocates.
    pub fn write(&mut self, var: &VarRef, value: &Value) -> Result<(), ValueError> {
        let v = self.encode(var, value)?;
        self.put(var, v, value);
        Ok(())
    }

    pub(super) fn encode(&self, var: &VarRef, value: &Value) -> Result<u64, ValueError> {
        match (&var.ty, var.bit) {
            (_, Some(_)) => Value::to_slot(value, Elem::Bool, None),
            (Type::String(_) | Type::WString(_), None) => match value {
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
                let r = repr_of(&var.ty);
                let old = self.vm.ld(slot, r);
                self.vm.st(slot, r, (old & !(1 << b)) | ((v & 1) << b));
            }
            (Type::String(cap), None, Value::String(text)) => {
                let mut bytes = [0u8; crate::types::MAX_STRING_LEN as usize + 1];
                let n = crate::strings::windows_1252(text, &mut bytes);
                crate::strings::write(&mut self.vm.mem, slot, *cap, &bytes[..n])
            }
            (Type::WString(cap), None, Value::String(text)) => {
                let mut units = [0u16; crate::types::MAX_STRING_LEN as usize + 1];
                let n = crate::strings::utf16_units(text, &mut units);
                crate::strings::write_units(&mut self.vm.mem, slot, *cap, true, &units[..n])
            }
            _ => self.vm.st(slot, repr_of(&var.ty), v),
        }
    }

    /// Parses IEC text (`TRUE`, `42`, `2.5`, `T#20ms`, an enumeration value name) for a
    /// variable.
    ///
    /// Real-time: no (allocates).
    pub fn parse_value(&self, var: &VarRef, text: &str) -> Result<Value, ValueError> {
        match (&var.ty, var.bit) {
            (_, Some(_)) => Value::parse(text, Elem::Bool),
            (Type::String(_) | Type::WString(_), None) => {
                // 'text' for a STRING, "text" for a WSTRING, or the bare text.
                let quote = if matches!(var.ty, Type::WString(_)) {
                    '"'
                } else {
                    '\''
                };
                let t = text.trim();
                let t = t
                    .strip_prefix(quote)
                    .and_then(|x| x.strip_suffix(quote))
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
    ///
    /// Real-time: no (allocates).
    pub fn force(&mut self, var: &VarRef, value: &Value) -> Result<(), MonitorError> {
        // Error texts are built only on error: forcing itself does not allocate.
        let name = || format!("address {}", var.slot);
        if var.bit.is_some() || var.elem().is_none() {
            return Err(MonitorError::NotScalar(name()));
        }
        let v = self
            .encode(var, value)
            .map_err(|error| MonitorError::Value {
                name: name(),
                error,
            })?;
        match self.forces.iter_mut().find(|(s, ..)| *s == var.slot) {
            Some(f) => f.2 = v,
            None => {
                if self.forces.len() >= self.options.max_forces {
                    return Err(MonitorError::ForceTableFull(self.options.max_forces));
                }
                self.forces.push((var.slot, repr_of(&var.ty), v));
            }
        }
        self.put(var, v, value);
        Ok(())
    }

    /// Releases a forced variable; it keeps its value until the program or the input
    /// image changes it.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn unforce(&mut self, var: &VarRef) {
        self.forces.retain(|(s, ..)| *s != var.slot);
    }

    /// Releases every force.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn unforce_all(&mut self) {
        self.forces.clear();
    }

    /// Byte addresses of the variables currently forced ([`VarRef::slot`]).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn forced_slots(&self) -> impl Iterator<Item = u32> + '_ {
        self.forces.iter().map(|(s, ..)| *s)
    }
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
                    let members = p.member_symbols(&ty).ok_or_else(bad)?;
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
