//! Calls of functions and function blocks: argument binding.

use super::*;

fn is_counter(pou: &str) -> bool {
    matches!(pou, "CTU" | "CTD" | "CTUD")
}

/// Bound call arguments: whether they may be written straight into the parameters, the
/// inputs and the `=>` outputs.
type BoundArgs = (bool, Box<[ArgIn]>, Box<[ArgOut]>);

impl<'a> Compiler<'a> {
    // ---------------------------------------------------------------- calls

    pub(super) fn call_stmt(
        &mut self,
        target: &Access,
        args: &[Arg],
        sc: &mut Scope,
        pos: Pos,
    ) -> R<StmtKind> {
        if target.parts.is_empty() && self.lookup(&target.root, sc).is_none() {
            let te = self.call_expr(&target.root, args, sc, pos, None)?;
            return Ok(StmtKind::Eval(te.e));
        }
        // `instance.method(...)` as a statement.
        if let Some(ast::Part::Field(m)) = target.parts.last() {
            let prefix = Access {
                root: target.root.clone(),
                parts: target.parts[..target.parts.len() - 1].to_vec(),
            };
            let is_method = match self.receiver(Some(&prefix), sc) {
                Ok(Some(r)) => self.has_member(&r, &m.text, Invoke::Method),
                _ => false,
            };
            if is_method {
                let te = self.method_call(&prefix, m, args, sc, pos)?;
                return Ok(StmtKind::Eval(te.e));
            }
        }
        // `SUPER^(...)`: the base block's body on this instance.
        if target.root.text == "SUPER"
            && matches!(target.parts.as_slice(), [ast::Part::Deref(_)])
            && !sc.vars.contains_key("SUPER")
        {
            let lv = self.access(target, sc)?;
            let Type::Fb(base) = lv.ty else {
                return Err(self.e(pos, ErrorKind::Invalid, "SUPER^ needs a base block"));
            };
            let name = self.fbs[base as usize].name.clone();
            let members = self.fbs[base as usize].members.clone();
            let (direct, ins, outs) = self.bind_args(&name, &members, args, sc, pos)?;
            return Ok(StmtKind::CallFb(Box::new(FbCall {
                instance: Place::Rel(0),
                kind: FbKind::User(self.fbs[base as usize].body),
                direct,
                args: ins,
                outs,
            })));
        }
        let lv = self.access(target, sc)?;
        let Type::Fb(id) = lv.ty else {
            return Err(self.e(
                target.root.pos,
                ErrorKind::TypeMismatch,
                format!("'{}' is not a function block instance", target.root.text),
            ));
        };
        let fb_name = self.fbs[id as usize].name.clone();
        let members = self.fbs[id as usize].members.clone();
        // CODESYS and TwinCAT name some inputs of the standard blocks otherwise.
        let renamed: Vec<Arg>;
        let args = match self.fbs[id as usize].std {
            Some(std) => {
                renamed = args
                    .iter()
                    .map(|a| match a {
                        Arg::Input(n, e) => match std.iec_input_name(&n.text) {
                            Some(iec) => Arg::Input(
                                Name {
                                    text: iec.to_string(),
                                    pos: n.pos,
                                },
                                e.clone(),
                            ),
                            None => a.clone(),
                        },
                        _ => a.clone(),
                    })
                    .collect();
                &renamed[..]
            }
            None => args,
        };
        let (direct, ins, outs) = self.bind_args(&fb_name, &members, args, sc, pos)?;
        let kind = match self.fbs[id as usize].std {
            Some(s) => FbKind::Std(s),
            None => FbKind::User(self.fbs[id as usize].body),
        };
        let instance = self.place(lv);
        Ok(StmtKind::CallFb(Box::new(FbCall {
            instance,
            kind,
            direct,
            args: ins,
            outs,
        })))
    }

    /// Matches formal and informal arguments to parameters.
    pub(super) fn bind_args(
        &mut self,
        pou: &str,
        params: &[Member],
        args: &[Arg],
        sc: &mut Scope,
        pos: Pos,
    ) -> R<BoundArgs> {
        let positional: Vec<&Member> = params
            .iter()
            .filter(|m| matches!(m.kind, VarKind::Input | VarKind::InOut))
            .collect();
        let mut ins: Vec<ArgIn> = Vec::new();
        let mut outs: Vec<ArgOut> = Vec::new();
        let mut given: HashSet<String> = HashSet::new();
        let mut k = 0usize;
        let mut calls_user = false;
        for a in args {
            match a {
                Arg::Positional(e) => {
                    if !given.is_empty() && k == 0 {
                        return Err(self.e(
                            e.pos(),
                            ErrorKind::WrongArgument,
                            "positional arguments must come before named ones",
                        ));
                    }
                    let Some(m) = positional.get(k).copied() else {
                        return Err(self.e(
                            e.pos(),
                            ErrorKind::WrongArgument,
                            format!("{pou} takes {} positional arguments", positional.len()),
                        ));
                    };
                    k += 1;
                    given.insert(m.name.clone());
                    let arg = self.arg_in(pou, m, e, sc, &mut calls_user)?;
                    ins.push(arg);
                }
                Arg::Input(n, e) => {
                    let Some(m) = params.iter().find(|m| m.name == n.text) else {
                        return Err(self.e(
                            n.pos,
                            ErrorKind::WrongArgument,
                            format!("{pou} has no parameter '{}'", n.text),
                        ));
                    };
                    if !matches!(m.kind, VarKind::Input | VarKind::InOut) {
                        return Err(self.e(
                            n.pos,
                            ErrorKind::WrongArgument,
                            format!("'{}' of {pou} is an output; use '=>'", n.text),
                        ));
                    }
                    if !given.insert(m.name.clone()) {
                        return Err(self.e(
                            n.pos,
                            ErrorKind::WrongArgument,
                            format!("'{}' is given twice", n.text),
                        ));
                    }
                    let arg = self.arg_in(pou, &m.clone(), e, sc, &mut calls_user)?;
                    ins.push(arg);
                }
                Arg::Output(n, target, negate) => {
                    if let Some(out) = self.bind_output(pou, params, n, target, *negate, sc)? {
                        outs.push(out);
                    }
                }
            }
        }
        for m in params {
            if m.kind == VarKind::InOut && !given.contains(&m.name) {
                return Err(self.e(
                    pos,
                    ErrorKind::WrongArgument,
                    format!("VAR_IN_OUT '{}' of {pou} must be given", m.name),
                ));
            }
        }
        Ok((!calls_user, ins.into_boxed_slice(), outs.into_boxed_slice()))
    }

    /// `n => target` (`negate`: `NOT n => target`): the output's copy to its target after
    /// the call, none without a target.
    fn bind_output(
        &mut self,
        pou: &str,
        params: &[Member],
        n: &Name,
        target: &Option<Access>,
        negate: bool,
        sc: &mut Scope,
    ) -> R<Option<ArgOut>> {
        let Some(m) = params.iter().find(|m| m.name == n.text).cloned() else {
            return Err(self.e(
                n.pos,
                ErrorKind::WrongArgument,
                format!("{pou} has no parameter '{}'", n.text),
            ));
        };
        if m.kind != VarKind::Output {
            return Err(self.e(
                n.pos,
                ErrorKind::WrongArgument,
                format!("'{}' of {pou} is not an output", n.text),
            ));
        }
        let Some(t) = target else {
            return Ok(None);
        };
        let lv = self.access(t, sc)?;
        self.check_writable(&lv, t.root.pos)?;
        if negate && !m.ty.is_bool() {
            return Err(self.e(
                n.pos,
                ErrorKind::WrongArgument,
                "only BOOL outputs can be negated",
            ));
        }
        // CODESYS and TwinCAT declare the counters' CV as WORD: any integer
        // or bit-string target takes it, wrapped to its width.
        let counter_cv = is_counter(pou) && m.name == "CV";
        let wrap = lv
            .ty
            .elem()
            .filter(|e| counter_cv && (e.is_int() || e.is_bit()) && *e != Elem::Int)
            .map(ik);
        let ok = wrap.is_some()
            || lv.ty == m.ty
            || matches!(
                (&m.ty, &lv.ty),
                (Type::String(_), Type::String(_)) | (Type::WString(_), Type::WString(_))
            )
            || matches!((m.ty.elem(), lv.ty.elem()), (Some(a), Some(b)) if widens(a, b) && !matches!(lv.ty, Type::Subrange(..)));
        if !ok || lv.bit.is_some() {
            return Err(self.e(
                t.root.pos,
                ErrorKind::WrongArgument,
                format!(
                    "output '{}' is {}, the target is {}",
                    n.text,
                    self.type_name(&m.ty),
                    self.type_name(&lv.ty)
                ),
            ));
        }
        if wrap.is_none()
            && m.ty.elem() != lv.ty.elem()
            && m.ty.scalar().is_some()
            && m.ty.elem() != Some(Elem::Bool)
        {
            // Widening outputs: read through a conversion is not expressible as a
            // copy, so only same-encoding widenings are accepted.
            let (f, t) = (
                m.ty.elem().unwrap_or(Elem::Bool),
                lv.ty.elem().unwrap_or(Elem::Bool),
            );
            if f.is_real() != t.is_real() {
                return Err(self.e(
                    t_root(target),
                    ErrorKind::WrongArgument,
                    format!("output '{}' is {}; convert it explicitly", n.text, f.name()),
                ));
            }
        }
        let store = self.store_kind(&lv.ty);
        Ok(Some(ArgOut {
            param: m.offset,
            src: repr_of(&m.ty),
            target: self.place(lv),
            store,
            negate,
            wrap,
        }))
    }

    pub(super) fn arg_in(
        &mut self,
        pou: &str,
        m: &Member,
        e: &AExpr,
        sc: &mut Scope,
        calls_user: &mut bool,
    ) -> R<ArgIn> {
        if contains_user_call(e, self) {
            *calls_user = true;
        }
        if m.kind == VarKind::InOut {
            let AExpr::Var(a) = e else {
                return Err(self.e(
                    e.pos(),
                    ErrorKind::WrongArgument,
                    format!("VAR_IN_OUT '{}' of {pou} needs a variable", m.name),
                ));
            };
            let lv = self.access(a, sc)?;
            self.check_writable(&lv, a.root.pos)?;
            if !self.same_or_derived(&lv.ty, &m.ty) || lv.bit.is_some() {
                return Err(self.e(
                    e.pos(),
                    ErrorKind::WrongArgument,
                    format!(
                        "VAR_IN_OUT '{}' is {}, the variable is {}",
                        m.name,
                        self.type_name(&m.ty),
                        self.type_name(&lv.ty)
                    ),
                ));
            }
            let temp = self.alloc(8, e.pos())?;
            let p = self.place(lv);
            return Ok(ArgIn {
                value: vm::Expr::RefOf(p),
                temp,
                param: m.offset,
                store: Store::Scalar(Repr::U64),
            });
        }
        if let Type::Reference(t) = &m.ty {
            // A REFERENCE input is bound to the variable given.
            let value = match e {
                AExpr::Lit(Literal::Int(0), _) => vm::Expr::Const(0),
                AExpr::Var(a) => {
                    let lv = self.access(a, sc)?;
                    if !self.same_or_derived(&lv.ty, t) || lv.bit.is_some() {
                        return Err(self.e(
                            e.pos(),
                            ErrorKind::WrongArgument,
                            format!(
                                "'{}' of {pou} is a REFERENCE TO {}, the variable is {}",
                                m.name,
                                self.type_name(t),
                                self.type_name(&lv.ty)
                            ),
                        ));
                    }
                    vm::Expr::RefOf(self.place(lv))
                }
                _ => {
                    return Err(self.e(
                        e.pos(),
                        ErrorKind::WrongArgument,
                        format!("'{}' of {pou} is a REFERENCE: give a variable", m.name),
                    ));
                }
            };
            let temp = self.alloc(8, e.pos())?;
            return Ok(ArgIn {
                value,
                temp,
                param: m.offset,
                store: Store::Scalar(Repr::U64),
            });
        }
        let te = self.expr(e, sc, Some(&m.ty))?;
        // The counters' PV is a WORD in CODESYS and TwinCAT: any integer or bit string.
        if is_counter(pou) && m.name == "PV" {
            if let Ty::T(Type::Elem(from)) = &te.ty {
                let from = *from;
                if (from.is_int() || from.is_bit()) && from != Elem::Int {
                    let value = self.conversion(te.e, from, Elem::Int);
                    let temp = self.alloc(8, e.pos())?;
                    return Ok(ArgIn {
                        value,
                        temp,
                        param: m.offset,
                        store: Store::Scalar(repr_of(&m.ty)),
                    });
                }
            }
        }
        // The motion blocks' Direction and BufferMode take the predefined enumerations.
        if pou.starts_with("MC_") && matches!(m.name.as_str(), "DIRECTION" | "BUFFERMODE") {
            if let Ty::T(Type::Enum(id)) = &te.ty {
                let name = self.enums[*id as usize].name.as_str();
                if matches!(name, "MC_DIRECTION" | "MC_BUFFER_MODE") {
                    let value = self.conversion(te.e, Elem::DInt, Elem::Int);
                    let temp = self.alloc(8, e.pos())?;
                    return Ok(ArgIn {
                        value,
                        temp,
                        param: m.offset,
                        store: Store::Scalar(repr_of(&m.ty)),
                    });
                }
            }
        }
        let value = self.coerce(te, &m.ty, e.pos()).map_err(|mut er| {
            er.kind = ErrorKind::WrongArgument;
            er.message = format!("argument '{}' of {pou}: {}", m.name, er.message);
            er
        })?;
        let store = self.store_kind(&m.ty);
        let temp = self.alloc(size_of(self, &m.ty), e.pos())?;
        Ok(ArgIn {
            value,
            temp,
            param: m.offset,
            store,
        })
    }

    pub(super) fn call_expr(
        &mut self,
        name: &Name,
        args: &[Arg],
        sc: &mut Scope,
        pos: Pos,
        expect: Option<&Type>,
    ) -> R<TE> {
        if let Some(id) = self.func_id(name)? {
            let (fname, params, ret) = {
                let f = &self.funcs[id as usize];
                (f.name.clone(), f.params.clone(), f.ret.clone())
            };
            let (direct, ins, outs) = self.bind_args(&fname, &params, args, sc, pos)?;
            sc.calls.push(id);
            let call = vm::Expr::Call(Box::new(FnCall {
                func: id,
                direct,
                args: ins,
                outs,
            }));
            return Ok(match ret {
                Some(t) => TE {
                    ty: Ty::T(t),
                    e: call,
                },
                None => TE {
                    ty: Ty::T(Type::BOOL),
                    e: call,
                },
            });
        }
        if self
            .fn_by_name
            .get(&name.text)
            .is_some_and(|l| matches!(l, Lookup::Busy))
        {
            return Err(self.e(
                pos,
                ErrorKind::Invalid,
                format!(
                    "function '{}' calls itself (recursion is not allowed)",
                    name.text
                ),
            ));
        }
        // A method of the function block this body belongs to, called without instance.
        if let Some(fb) = sc.fb {
            if self.fbs[fb as usize]
                .methods
                .iter()
                .any(|x| x.0 == name.text)
            {
                let r = self.receiver(None, sc)?;
                if let Some(r) = r {
                    return self.invoke(r, name, Invoke::Method, args, sc, pos);
                }
            }
        }
        if let Some(te) = self.address_function(name, args, sc, pos)? {
            return Ok(te);
        }
        crate::builtins::call(self, name, args, sc, pos, expect)
    }

    /// `prefix.method(args)`: prefix must be an instance of a function block with that
    /// method (PRIVATE methods only from inside the block), or an interface.
    pub(super) fn method_call(
        &mut self,
        prefix: &Access,
        m: &Name,
        args: &[Arg],
        sc: &mut Scope,
        pos: Pos,
    ) -> R<TE> {
        let Some(r) = self.receiver(Some(prefix), sc)? else {
            return Err(self.e(
                m.pos,
                ErrorKind::TypeMismatch,
                format!(
                    "'{}' is not a function block instance or an interface",
                    prefix.root.text
                ),
            ));
        };
        self.invoke(r, m, Invoke::Method, args, sc, pos)
    }

    /// The instance a method or property is called on. `None` as prefix: the block whose
    /// body is being compiled (a bare `M()`).
    pub(super) fn receiver(
        &mut self,
        prefix: Option<&Access>,
        sc: &mut Scope,
    ) -> R<Option<Receiver>> {
        let user_subtypes = |c: &Self, id: u32| -> Vec<u32> {
            (0..c.fbs.len() as u32)
                .filter(|x| c.fbs[*x as usize].std.is_none() && c.fb_extends(*x, id))
                .collect()
        };
        let Some(a) = prefix else {
            return Ok(sc.fb.map(|fb| Receiver {
                instance: None,
                static_fb: Some(fb),
                iface: None,
                cands: user_subtypes(self, fb),
            }));
        };
        let is_self = |n: &str| {
            (n == "THIS" || n == "SUPER")
                && !sc.vars.contains_key(n)
                && matches!(a.parts.as_slice(), [ast::Part::Deref(_)])
        };
        if is_self(&a.root.text) {
            let lv = self.access(a, sc)?;
            let Type::Fb(id) = lv.ty else { return Ok(None) };
            let cands = if a.root.text == "SUPER" {
                vec![id] // SUPER^.M() calls the base's implementation
            } else {
                user_subtypes(self, id)
            };
            return Ok(Some(Receiver {
                instance: None,
                static_fb: Some(id),
                iface: None,
                cands,
            }));
        }
        let lv = self.access(a, sc)?;
        match lv.ty.clone() {
            Type::Fb(id) if self.fbs[id as usize].std.is_none() => {
                // Through a reference, pointer or VAR_IN_OUT the instance may be of a
                // derived type.
                let poly = lv.indirect || lv.inner.is_some();
                let cands = if poly {
                    user_subtypes(self, id)
                } else {
                    vec![id]
                };
                let instance = Some(self.place(lv));
                Ok(Some(Receiver {
                    instance,
                    static_fb: Some(id),
                    iface: None,
                    cands,
                }))
            }
            Type::Interface(i) => {
                let cands = (0..self.fbs.len() as u32)
                    .filter(|x| self.fbs[*x as usize].std.is_none() && self.fb_implements(*x, i))
                    .collect();
                let inst = self.deref_lv(lv, Type::Interface(i));
                let instance = Some(self.place(inst));
                Ok(Some(Receiver {
                    instance,
                    static_fb: None,
                    iface: Some(i),
                    cands,
                }))
            }
            _ => Ok(None),
        }
    }

    /// The function implementing `name` (method, or property getter or setter) in
    /// function block `fb`.
    fn member_fn(&self, fb: u32, name: &str, kind: Invoke) -> Option<(u32, bool)> {
        let f = &self.fbs[fb as usize];
        match kind {
            Invoke::Method => f.methods.iter().find(|x| x.0 == name).map(|x| (x.1, x.2)),
            Invoke::Get | Invoke::Set => {
                f.properties.iter().find(|x| x.name == name).and_then(|p| {
                    let id = if kind == Invoke::Get { p.get } else { p.set };
                    id.map(|i| (i, p.private))
                })
            }
        }
    }

    pub(super) fn has_member(&self, r: &Receiver, name: &str, kind: Invoke) -> bool {
        match (r.static_fb, r.iface) {
            (Some(fb), _) => self.member_fn(fb, name, kind).is_some(),
            (None, Some(i)) => {
                let it = &self.ifaces[i as usize];
                match kind {
                    Invoke::Method => it.methods.iter().any(|x| x.0 == name),
                    _ => it.properties.iter().any(|x| x.0 == name),
                }
            }
            _ => false,
        }
    }

    /// Calls a method or property accessor on a receiver: directly when one function
    /// can be meant, else by the instance's type tag.
    pub(super) fn invoke(
        &mut self,
        r: Receiver,
        m: &Name,
        kind: Invoke,
        args: &[Arg],
        sc: &mut Scope,
        pos: Pos,
    ) -> R<TE> {
        let what = match kind {
            Invoke::Method => "method",
            Invoke::Get => "readable property",
            Invoke::Set => "writable property",
        };
        let shown = match (r.static_fb, r.iface) {
            (Some(fb), _) => self.fbs[fb as usize].name.clone(),
            (None, Some(i)) => self.ifaces[i as usize].name.clone(),
            _ => String::new(),
        };
        if !self.has_member(&r, &m.text, kind) {
            return Err(self.e(
                m.pos,
                ErrorKind::Undeclared,
                format!("'{shown}' has no {what} '{}'", m.text),
            ));
        }
        if let Some(fb) = r.static_fb {
            if let Some((_, true)) = self.member_fn(fb, &m.text, kind) {
                let inside = sc
                    .fb
                    .is_some_and(|s| self.fb_extends(s, fb) || self.fb_extends(fb, s));
                if !inside {
                    return Err(self.e(
                        m.pos,
                        ErrorKind::Invalid,
                        format!("'{}' is PRIVATE to '{shown}'", m.text),
                    ));
                }
            }
        }
        // Distinct implementations among the candidate types.
        let mut fids: Vec<u32> = Vec::new();
        let mut cases: Vec<(u64, u32)> = Vec::new();
        for &c in &r.cands {
            if let Some((f, _)) = self.member_fn(c, &m.text, kind) {
                let k = match fids.iter().position(|x| *x == f) {
                    Some(k) => k,
                    None => {
                        fids.push(f);
                        fids.len() - 1
                    }
                };
                cases.push((c as u64 + 1, k as u32));
            }
        }
        let ret = match (fids.first(), r.iface) {
            (Some(f), _) => self.funcs[*f as usize].ret.clone(),
            (None, Some(i)) => {
                let it = &self.ifaces[i as usize];
                match kind {
                    Invoke::Method => it
                        .methods
                        .iter()
                        .find(|x| x.0 == m.text)
                        .and_then(|x| x.1.clone()),
                    Invoke::Get => it
                        .properties
                        .iter()
                        .find(|x| x.0 == m.text)
                        .map(|x| x.1.clone()),
                    Invoke::Set => None,
                }
            }
            _ => None,
        };
        let shown_m = format!("{shown}.{}", m.text);
        let mut calls = Vec::with_capacity(fids.len());
        for &f in &fids {
            let params = self.funcs[f as usize].params.clone();
            let (direct, ins, outs) = self.bind_args(&shown_m, &params, args, sc, pos)?;
            sc.calls.push(f);
            calls.push(FnCall {
                func: f,
                direct,
                args: ins,
                outs,
            });
        }
        let instance = r.instance.unwrap_or(Place::Rel(0));
        let e = if calls.len() == 1 && r.iface.is_none() {
            let call = calls
                .pop()
                .ok_or_else(|| self.e(pos, ErrorKind::Invalid, "no method"))?;
            vm::Expr::CallMethod(Box::new(vm::MethodCall { instance, call }))
        } else {
            vm::Expr::CallVirtual(Box::new(vm::VirtualCall {
                instance,
                cases: cases.into_boxed_slice(),
                calls: calls.into_boxed_slice(),
            }))
        };
        Ok(TE {
            ty: Ty::T(ret.unwrap_or(Type::BOOL)),
            e,
        })
    }

    /// `prefix.P` or a bare `P` inside a function block naming a PROPERTY.
    pub(super) fn property_of(
        &mut self,
        a: &Access,
        sc: &mut Scope,
    ) -> R<Option<(Receiver, Name)>> {
        match a.parts.last() {
            None => {
                if sc.vars.contains_key(&a.root.text) || self.globals.contains_key(&a.root.text) {
                    return Ok(None);
                }
                let Some(fb) = sc.fb else { return Ok(None) };
                if !self.fbs[fb as usize]
                    .properties
                    .iter()
                    .any(|p| p.name == a.root.text)
                {
                    return Ok(None);
                }
                Ok(self.receiver(None, sc)?.map(|r| (r, a.root.clone())))
            }
            Some(ast::Part::Field(p)) => {
                let prefix = Access {
                    root: a.root.clone(),
                    parts: a.parts[..a.parts.len() - 1].to_vec(),
                };
                let r = match self.receiver(Some(&prefix), sc) {
                    Ok(Some(r)) => r,
                    _ => return Ok(None),
                };
                let is_prop = self.has_member(&r, &p.text, Invoke::Get)
                    || self.has_member(&r, &p.text, Invoke::Set);
                Ok(is_prop.then(|| (r, p.clone())))
            }
            _ => Ok(None),
        }
    }

    /// ADR, SIZEOF, __ISVALIDREF.
    fn address_function(
        &mut self,
        name: &Name,
        args: &[Arg],
        sc: &mut Scope,
        pos: Pos,
    ) -> R<Option<TE>> {
        let f = name.text.as_str();
        if !matches!(f, "ADR" | "SIZEOF" | "__ISVALIDREF") {
            return Ok(None);
        }
        let [Arg::Positional(arg)] = args else {
            return Err(self.e(
                pos,
                ErrorKind::WrongArgument,
                format!("{f} takes one argument"),
            ));
        };
        let AExpr::Var(a) = arg else {
            return Err(self.e(
                arg.pos(),
                ErrorKind::WrongArgument,
                format!("{f} needs a variable"),
            ));
        };
        match f {
            "ADR" => {
                let lv = self.access(a, sc)?;
                if lv.bit.is_some() {
                    return Err(self.e(
                        arg.pos(),
                        ErrorKind::WrongArgument,
                        "ADR of a bit is not possible",
                    ));
                }
                let ty = Type::Pointer(Arc::new(lv.ty.clone()));
                Ok(Some(TE {
                    ty: Ty::T(ty),
                    e: vm::Expr::RefOf(self.place(lv)),
                }))
            }
            "SIZEOF" => {
                // A variable or a type name, in bytes as CODESYS lays it out.
                let ty = if a.parts.is_empty() && self.lookup(&a.root, sc).is_none() {
                    self.named_type(&a.root)?.0
                } else {
                    self.access(a, sc)?.ty
                };
                Ok(Some(TE {
                    ty: Ty::AnyInt(size_of(self, &ty) as i128),
                    e: vm::Expr::Const(0),
                }))
            }
            _ => {
                let lv = self.access_opt(a, sc, true)?;
                if !lv.ty.is_address() {
                    return Err(self.e(
                        arg.pos(),
                        ErrorKind::WrongArgument,
                        "__ISVALIDREF needs a REFERENCE, POINTER or interface",
                    ));
                }
                let p = self.place(lv);
                let load = match p {
                    Place::Abs(x) => vm::Expr::LoadAbs(x, Repr::U64),
                    Place::Rel(o) => vm::Expr::LoadRel(o, Repr::U64),
                    Place::Dyn(d) => vm::Expr::Load(d, Repr::U64),
                };
                Ok(Some(TE {
                    ty: Ty::T(Type::BOOL),
                    e: vm::Expr::BinK(Bin::Ne, Box::new(load), 0),
                }))
            }
        }
    }

    // Hooks for the builtins module.
    pub(crate) fn b_args(
        &mut self,
        args: &[Arg],
        sc: &mut Scope,
        fname: &str,
    ) -> R<Vec<(TE, Pos)>> {
        let mut out = Vec::new();
        for a in args {
            match a {
                Arg::Positional(e) | Arg::Input(_, e) => {
                    out.push((self.expr(e, sc, None)?, e.pos()))
                }
                Arg::Output(n, _, _) => {
                    return Err(self.e(
                        n.pos,
                        ErrorKind::WrongArgument,
                        format!("{fname} has no outputs"),
                    ));
                }
            }
        }
        Ok(out)
    }
}
