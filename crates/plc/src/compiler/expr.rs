//! Variable access, expressions, implicit conversions and constant folding.

use super::*;

fn address(t: &Ty) -> bool {
    matches!(t, Ty::T(x) if x.is_address())
}

impl<'a> Compiler<'a> {
    // ---------------------------------------------------------------- variable access

    pub(super) fn lookup(&mut self, n: &Name, sc: &Scope) -> Option<VarInfo> {
        if let Some(v) = sc.vars.get(&n.text) {
            return Some(v.clone());
        }
        self.globals.get(&n.text).cloned()
    }

    pub(super) fn access(&mut self, a: &Access, sc: &mut Scope) -> R<Lv> {
        self.access_opt(a, sc, false)
    }

    /// A place as a pointer or reference reads it: `lv` holds a byte address, the result
    /// is what it points to.
    pub(super) fn deref_lv(&self, lv: Lv, target: Type) -> Lv {
        let simple = lv.steps.is_empty() && !lv.indirect && lv.inner.is_none();
        let (base, inner) = if simple {
            let b = match lv.base {
                Base::Abs(a) => Base::Abs(a + lv.offset),
                Base::Rel(o) => Base::Rel(o + lv.offset),
            };
            (b, None)
        } else {
            let inner = DynPlace {
                base: lv.base,
                indirect: lv.indirect,
                offset: lv.offset,
                steps: lv.steps.into_boxed_slice(),
                inner: lv.inner,
                span: 8,
            };
            (Base::Abs(0), Some(Box::new(inner)))
        };
        Lv {
            ty: target,
            base,
            indirect: true,
            offset: 0,
            steps: Vec::new(),
            bit: None,
            readonly: None,
            const_val: None,
            inner,
            warn_on_write: None,
        }
    }

    /// The instance `THIS^` or `SUPER^` names inside a function block (SUPER^ as the base
    /// type).
    fn this_lv(&self, a: &Access, sc: &Scope) -> R<Option<Lv>> {
        let is_this = a.root.text == "THIS";
        let is_super = a.root.text == "SUPER";
        if !(is_this || is_super) || sc.vars.contains_key(&a.root.text) {
            return Ok(None);
        }
        let Some(fb) = sc.fb else {
            return Err(self.e(
                a.root.pos,
                ErrorKind::Invalid,
                format!("{} belongs inside a FUNCTION_BLOCK", a.root.text),
            ));
        };
        if !matches!(a.parts.first(), Some(Part::Deref(_))) {
            return Err(self.e(
                a.root.pos,
                ErrorKind::Syntax,
                format!("write {}^ (with '^')", a.root.text),
            ));
        }
        let ty = if is_super {
            match self.fbs[fb as usize].base {
                Some(b) => b,
                None => {
                    return Err(self.e(
                        a.root.pos,
                        ErrorKind::Invalid,
                        format!(
                            "SUPER^ needs a base block: '{}' has no EXTENDS",
                            self.fbs[fb as usize].name
                        ),
                    ));
                }
            }
        } else {
            fb
        };
        Ok(Some(Lv {
            ty: Type::Fb(ty),
            base: Base::Rel(0),
            indirect: false,
            offset: 0,
            steps: Vec::new(),
            bit: None,
            readonly: None,
            const_val: None,
            inner: None,
            warn_on_write: None,
        }))
    }

    /// A variable access; `keep_ref` leaves a final REFERENCE as the reference itself
    /// (the target of `REF=`) instead of what it points to.
    pub(super) fn access_opt(&mut self, a: &Access, sc: &mut Scope, keep_ref: bool) -> R<Lv> {
        if let Some(lv) = self.this_lv(a, sc)? {
            return self.access_parts(lv, a, &a.parts[1..], sc, keep_ref);
        }
        if a.root.text.starts_with('%') && self.lookup(&a.root, sc).is_none() {
            let toks = crate::lexer::tokenize(&a.root.text, self.file)?;
            if let Some(crate::lexer::Tok::Direct(d)) = toks.first().map(|t| &t.kind) {
                self.direct_var(d, a.root.pos)?;
            }
        }
        let Some(v) = self.lookup(&a.root, sc) else {
            return Err(self.e(
                a.root.pos,
                ErrorKind::Undeclared,
                format!("'{}' is not declared", a.root.text),
            ));
        };
        let (base, indirect) = match v.loc {
            Loc::Abs(x) => (Base::Abs(x), false),
            Loc::Rel(x) => (Base::Rel(x), false),
            Loc::IndAbs(x) => (Base::Abs(x), true),
            Loc::IndRel(x) => (Base::Rel(x), true),
        };
        let readonly = if v.constant {
            Some((
                ErrorKind::AssignToConstant,
                format!("'{}' is a CONSTANT", a.root.text),
            ))
        } else if v.input_area {
            Some((
                ErrorKind::AssignToInput,
                format!("'{}' is located in the input image (%I)", a.root.text),
            ))
        } else {
            None
        };
        let warn_on_write = (v.kind == VarKind::Input && !v.constant).then(|| {
            format!(
                "'{}' is a VAR_INPUT of this POU: writing it hides the caller's value until the next call",
                a.root.text
            )
        });
        let lv = Lv {
            ty: v.ty.clone(),
            base,
            indirect,
            offset: 0,
            steps: Vec::new(),
            bit: None,
            readonly,
            const_val: v.const_val,
            inner: None,
            warn_on_write,
        };
        self.access_parts(lv, a, &a.parts, sc, keep_ref)
    }

    fn access_parts(
        &mut self,
        mut lv: Lv,
        a: &Access,
        parts: &[Part],
        sc: &mut Scope,
        keep_ref: bool,
    ) -> R<Lv> {
        if let Type::Reference(t) = lv.ty.clone() {
            if !(keep_ref && parts.is_empty()) {
                // Writing through a reference input writes the caller's variable: no warning.
                let ro = lv.readonly.take();
                lv = self.deref_lv(lv, (*t).clone());
                lv.readonly = ro;
            }
        }
        for (k, p) in parts.iter().enumerate() {
            let last = k + 1 == parts.len();
            if lv.bit.is_some() {
                return Err(self.e(
                    a.root.pos,
                    ErrorKind::Invalid,
                    "nothing can follow a bit access",
                ));
            }
            lv.const_val = None;
            lv.warn_on_write = None;
            match p {
                Part::Deref(pos) => {
                    let Type::Pointer(t) = lv.ty.clone() else {
                        return Err(self.e(
                            *pos,
                            ErrorKind::TypeMismatch,
                            format!(
                                "'^' dereferences a POINTER; here it follows a {}",
                                self.type_name(&lv.ty)
                            ),
                        ));
                    };
                    lv = self.deref_lv(lv, (*t).clone());
                }
                Part::Field(f) => self.field_part(&mut lv, a, f, sc)?,
                Part::Index(idx, pos) => self.index_part(&mut lv, a, idx, *pos, sc)?,
                Part::Bit(b, pos) => self.bit_part(&mut lv, *b, *pos)?,
            }
            if let Type::Reference(t) = lv.ty.clone() {
                if !(keep_ref && last) {
                    let ro = lv.readonly.take();
                    lv = self.deref_lv(lv, (*t).clone());
                    lv.readonly = ro;
                }
            }
        }
        Ok(lv)
    }

    /// `.f`: a structure's field or a function block's member.
    fn field_part(&self, lv: &mut Lv, a: &Access, f: &Name, sc: &Scope) -> R<()> {
        match lv.ty.clone() {
            Type::Struct(id) => {
                let st = &self.structs[id as usize].0;
                let Some(field) = st.fields.iter().find(|x| x.name == f.text) else {
                    return Err(self.e(
                        f.pos,
                        ErrorKind::Undeclared,
                        format!("{} has no field '{}'", st.name, f.text),
                    ));
                };
                lv.offset += field.offset;
                lv.ty = field.ty.clone();
            }
            Type::Fb(id) => {
                let fb = &self.fbs[id as usize];
                let Some(m) = fb.members.iter().find(|x| x.name == f.text).cloned() else {
                    return Err(self.e(
                        f.pos,
                        ErrorKind::Undeclared,
                        format!("{} has no member '{}'", fb.name, f.text),
                    ));
                };
                // Inside the block (THIS^.x) or a block derived from it, every member.
                let inside = sc.fb.is_some_and(|s| self.fb_extends(s, id));
                if !inside && !matches!(m.kind, VarKind::Input | VarKind::Output | VarKind::InOut) {
                    return Err(self.e(
                        f.pos,
                        ErrorKind::Invalid,
                        format!("'{}' is internal to {}", f.text, fb.name),
                    ));
                }
                if m.kind == VarKind::InOut {
                    return Err(self.e(
                        f.pos,
                        ErrorKind::Invalid,
                        "VAR_IN_OUT members cannot be accessed from outside",
                    ));
                }
                if m.kind == VarKind::Output && !inside && lv.readonly.is_none() {
                    lv.readonly = Some((
                        ErrorKind::Invalid,
                        format!(
                            "output '{}' of {} can only be written by the block",
                            f.text, fb.name
                        ),
                    ));
                }
                lv.offset += m.offset;
                lv.ty = m.ty.clone();
            }
            _ => {
                return Err(self.e(
                    f.pos,
                    ErrorKind::TypeMismatch,
                    format!("'{}' is not a structure or function block", a.root.text),
                ));
            }
        }
        Ok(())
    }

    /// `[i, j]`: an array's element, its offset added where the indices are constant and an
    /// index step otherwise.
    fn index_part(
        &mut self,
        lv: &mut Lv,
        a: &Access,
        idx: &[AExpr],
        pos: Pos,
        sc: &mut Scope,
    ) -> R<()> {
        let Type::Array(at) = lv.ty.clone() else {
            return Err(self.e(
                pos,
                ErrorKind::TypeMismatch,
                format!("'{}' is not an array", a.root.text),
            ));
        };
        if idx.len() != at.dims.len() {
            return Err(self.e(
                pos,
                ErrorKind::WrongArgument,
                format!(
                    "array has {} dimensions, {} indices given",
                    at.dims.len(),
                    idx.len()
                ),
            ));
        }
        // Row-major strides.
        let mut stride = at.elem_size as u64;
        let mut strides = vec![0u64; at.dims.len()];
        for (k, (l, h)) in at.dims.iter().enumerate().rev() {
            strides[k] = stride;
            stride *= (h - l + 1) as u64;
        }
        for (k, ie) in idx.iter().enumerate() {
            let (lo, hi) = at.dims[k];
            let te = self.expr(ie, sc, None)?;
            let ok = match &te.ty {
                Ty::AnyInt(_) => true,
                Ty::T(t) => t
                    .elem()
                    .is_some_and(|e| e.is_int() || (self.codesys_conversions && e.is_bit())),
                Ty::AnyReal(_) => false,
            };
            if !ok {
                return Err(self.e(
                    ie.pos(),
                    ErrorKind::TypeMismatch,
                    format!(
                        "array index must be an integer, not {}",
                        self.ty_name(&te.ty)
                    ),
                ));
            }
            let ity = match &te.ty {
                Ty::T(t) => t.clone(),
                _ => Type::Elem(Elem::LInt),
            };
            let e = self.coerce(te, &ity, ie.pos())?;
            if let vm::Expr::Const(c) = e {
                let i = if ity.elem().is_some_and(|e| ik(e).signed()) {
                    c as i64
                } else {
                    c.min(i64::MAX as u64) as i64
                };
                if i < lo || i > hi {
                    return Err(self.e(
                        ie.pos(),
                        ErrorKind::Invalid,
                        format!("index {i} is outside {lo}..{hi}"),
                    ));
                }
                lv.offset += ((i - lo) as u64 * strides[k]) as u32;
            } else {
                lv.steps.push(IndexStep {
                    index: e,
                    low: lo,
                    len: (hi - lo + 1) as u64,
                    stride: strides[k] as u32,
                });
            }
        }
        lv.ty = at.elem.clone();
        Ok(())
    }

    /// `.n`: a bit of an integer or bit string.
    fn bit_part(&self, lv: &mut Lv, b: u8, pos: Pos) -> R<()> {
        let Some(e) = lv
            .ty
            .elem()
            .filter(|e| e.int_kind().is_some() && *e != Elem::Bool && *e != Elem::Time)
        else {
            return Err(self.e(
                pos,
                ErrorKind::TypeMismatch,
                "bit access needs an integer or bit-string variable",
            ));
        };
        if b as u32 >= e.bits() {
            return Err(self.e(
                pos,
                ErrorKind::Invalid,
                format!("{} has no bit {b}", e.name()),
            ));
        }
        lv.bit = Some(b);
        Ok(())
    }

    pub(super) fn place(&self, lv: Lv) -> Place {
        if lv.steps.is_empty() && !lv.indirect && lv.inner.is_none() {
            match lv.base {
                Base::Abs(a) => Place::Abs(a + lv.offset),
                Base::Rel(o) => Place::Rel(o + lv.offset),
            }
        } else {
            let span = size_of(self, &lv.ty);
            Place::Dyn(Box::new(DynPlace {
                base: lv.base,
                indirect: lv.indirect,
                offset: lv.offset,
                steps: lv.steps.into_boxed_slice(),
                inner: lv.inner,
                span,
            }))
        }
    }

    pub(super) fn load(&self, lv: Lv) -> TE {
        if let Some(c) = lv.const_val {
            return TE {
                ty: Ty::T(lv.ty),
                e: vm::Expr::Const(c),
            };
        }
        let ty = lv.ty.clone();
        let bit = lv.bit;
        let repr = ty.repr();
        let p = self.place(lv);
        let e = match repr {
            None => vm::Expr::AddrOf(p),
            Some(r) => match p {
                Place::Abs(a) => vm::Expr::LoadAbs(a, r),
                Place::Rel(o) => vm::Expr::LoadRel(o, r),
                Place::Dyn(d) => vm::Expr::Load(d, r),
            },
        };
        match bit {
            Some(b) => TE {
                ty: Ty::T(Type::BOOL),
                e: vm::Expr::Un(Un::Bit(b), Box::new(e)),
            },
            None => TE { ty: Ty::T(ty), e },
        }
    }

    // ---------------------------------------------------------------- expressions

    pub(super) fn string_literal(&mut self, s: &[u8], pos: Pos) -> R<TE> {
        let cap = s.len().max(1) as u16;
        let a = match self.string_lits.get(s) {
            Some(a) => *a,
            None => {
                let a = self.alloc(string_bytes(cap), pos)?;
                crate::strings::write(&mut self.image, a as usize, cap, s);
                self.string_lits.insert(s.to_vec(), a);
                a
            }
        };
        Ok(TE {
            ty: Ty::T(Type::String(cap)),
            e: vm::Expr::AddrOf(Place::Abs(a)),
        })
    }

    pub(super) fn wide_string_literal(&mut self, s: &[u16], pos: Pos) -> R<TE> {
        let cap = s.len().max(1) as u16;
        let a = self.alloc(crate::types::wstring_bytes(cap), pos)?;
        crate::strings::write_units(&mut self.image, a as usize, cap, true, s);
        Ok(TE {
            ty: Ty::T(Type::WString(cap)),
            e: vm::Expr::AddrOf(Place::Abs(a)),
        })
    }

    /// A temporary for a STRING, or a WSTRING if `wide`, of the longest length.
    pub(super) fn string_temp(&mut self, pos: Pos, wide: bool) -> R<u32> {
        if wide {
            self.alloc(crate::types::wstring_bytes(MAX_STRING_LEN), pos)
        } else {
            self.alloc(string_bytes(MAX_STRING_LEN), pos)
        }
    }

    pub(super) fn expr(&mut self, e: &AExpr, sc: &mut Scope, expect: Option<&Type>) -> R<TE> {
        match e {
            AExpr::Lit(l, pos) => self.literal(l, *pos),
            AExpr::Typed(tn, inner) => {
                let (t, _) = self.named_type(tn)?;
                let te = self.expr(inner, sc, Some(&t))?;
                let v = self.coerce(te, &t, inner.pos())?;
                Ok(TE { ty: Ty::T(t), e: v })
            }
            AExpr::EnumValue(tn, v) => self.enum_value(tn, v),
            AExpr::Var(a) => self.variable(a, sc, expect),
            AExpr::Direct(d, pos) => {
                let name = d.to_string();
                let root = Name {
                    text: name,
                    pos: *pos,
                };
                let lv = self.access(
                    &Access {
                        root,
                        parts: Vec::new(),
                    },
                    sc,
                )?;
                Ok(self.load(lv))
            }
            AExpr::Unary(op, inner, pos) => {
                let te = self.expr(inner, sc, expect)?;
                self.unary(*op, te, *pos)
            }
            AExpr::Binary(..) => self.binary_chain(e, sc, expect),
            AExpr::MethodCall(target, args, pos) => self.method_call_value(target, args, sc, *pos),
            AExpr::Call(name, args, pos) => self.call_value(name, args, sc, *pos, expect),
        }
    }

    fn literal(&mut self, l: &Literal, pos: Pos) -> R<TE> {
        Ok(match l {
            Literal::Int(v) => TE {
                ty: Ty::AnyInt(*v as i128),
                e: vm::Expr::Const(0),
            },
            Literal::Real(v) => TE {
                ty: Ty::AnyReal(*v),
                e: vm::Expr::Const(0),
            },
            Literal::Time(ns) => {
                let ns = i64::try_from(*ns)
                    .map_err(|_| self.e(pos, ErrorKind::Invalid, "duration is too large"))?;
                TE {
                    ty: Ty::T(Type::Elem(Elem::Time)),
                    e: vm::Expr::Const(ns as u64),
                }
            }
            Literal::Bool(b) => TE {
                ty: Ty::T(Type::BOOL),
                e: vm::Expr::Const(*b as u64),
            },
            Literal::Moment(k, ns) => TE {
                ty: Ty::T(Type::Elem(k.elem())),
                e: vm::Expr::Const(*ns as u64),
            },
            Literal::Str(s) => return self.string_literal(s, pos),
            Literal::WStr(s) => return self.wide_string_literal(s, pos),
        })
    }

    /// `Type#value`.
    fn enum_value(&mut self, tn: &Name, v: &Name) -> R<TE> {
        let (t, _) = self.named_type(tn)?;
        let Type::Enum(id) = t else {
            return Err(self.e(
                tn.pos,
                ErrorKind::TypeMismatch,
                format!("'{}' is not an enumeration", tn.text),
            ));
        };
        let Some((_, val)) = self.enums[id as usize]
            .values
            .iter()
            .find(|(n, _)| n == &v.text)
        else {
            return Err(self.e(
                v.pos,
                ErrorKind::Undeclared,
                format!("{} has no value '{}'", tn.text, v.text),
            ));
        };
        Ok(TE {
            ty: Ty::T(Type::Enum(id)),
            e: vm::Expr::Const(*val as u64),
        })
    }

    /// A variable, an enumeration's value or a property.
    fn variable(&mut self, a: &Access, sc: &mut Scope, expect: Option<&Type>) -> R<TE> {
        // `E_Mode.Idle`: a qualified enumeration value (CODESYS, TwinCAT).
        if let [Part::Field(v)] = a.parts.as_slice() {
            if self.lookup(&a.root, sc).is_none() && self.type_asts.contains_key(&a.root.text) {
                return self.expr(&AExpr::EnumValue(a.root.clone(), v.clone()), sc, expect);
            }
        }
        if let Some((r, p)) = self.property_of(a, sc)? {
            return self.invoke(r, &p, Invoke::Get, &[], sc, p.pos);
        }
        if a.parts.is_empty() && self.lookup(&a.root, sc).is_none() {
            if let Some(cands) = self.enum_values.get(&a.root.text) {
                let pick = match expect {
                    Some(Type::Enum(id)) => cands.iter().find(|(e, _)| e == id).copied(),
                    _ => None,
                }
                .or(if cands.len() == 1 {
                    Some(cands[0])
                } else {
                    None
                });
                return match pick {
                    Some((id, v)) => Ok(TE {
                        ty: Ty::T(Type::Enum(id)),
                        e: vm::Expr::Const(v as u64),
                    }),
                    None => Err(self.e(
                        a.root.pos,
                        ErrorKind::Invalid,
                        format!(
                            "'{}' names values of several enumerations; write Type#{}",
                            a.root.text, a.root.text
                        ),
                    )),
                };
            }
        }
        let lv = self.access(a, sc)?;
        // An instance given where an interface (or VAR_IN_OUT of its type) is
        // expected stands for itself.
        let to_interface = matches!(expect, Some(Type::Interface(_)));
        if let (Type::Fb(_), false) = (&lv.ty, to_interface) {
            return Err(self.e(
                a.root.pos,
                ErrorKind::TypeMismatch,
                "a function block instance is not a value; read one of its outputs",
            ));
        }
        Ok(self.load(lv))
    }

    fn binary_chain(&mut self, e: &AExpr, sc: &mut Scope, expect: Option<&Type>) -> R<TE> {
        // `a + b - c + ...` is a left-deep tree: its left spine is walked here in a
        // loop, not by recursion, so a long chain costs no stack per operator.
        let mut spine = Vec::new();
        let mut leftmost = e;
        while let AExpr::Binary(op, l, r, pos) = leftmost {
            spine.push((*op, &**r, *pos));
            leftmost = l;
        }
        let mut lt = self.expr(leftmost, sc, expect)?;
        for (op, r, pos) in spine.into_iter().rev() {
            let hint = match &lt.ty {
                Ty::T(t) => Some(t.clone()),
                _ => expect.cloned(),
            };
            let rt = self.expr(r, sc, hint.as_ref())?;
            lt = self.binary(op, lt, rt, pos)?;
        }
        Ok(lt)
    }

    /// `instance.method(args)` as a value.
    fn method_call_value(
        &mut self,
        target: &(Access, Name),
        args: &[Arg],
        sc: &mut Scope,
        pos: Pos,
    ) -> R<TE> {
        let (prefix, m) = target;
        let te = self.method_call(prefix, m, args, sc, pos)?;
        if let vm::Expr::CallMethod(mc) = &te.e {
            if self
                .funcs
                .get(mc.call.func as usize)
                .is_some_and(|f| f.ret.is_none())
            {
                return Err(self.e(
                    pos,
                    ErrorKind::TypeMismatch,
                    format!("method '{}' returns no value", m.text),
                ));
            }
        }
        Ok(te)
    }

    /// A function call as a value.
    fn call_value(
        &mut self,
        name: &Name,
        args: &[Arg],
        sc: &mut Scope,
        pos: Pos,
        expect: Option<&Type>,
    ) -> R<TE> {
        let is = |a: &Arg, n: &str| match a {
            Arg::Input(x, _) | Arg::Output(x, _, _) => x.text == n,
            Arg::Positional(_) => false,
        };
        if args.iter().any(|a| is(a, "EN") || is(a, "ENO")) {
            return self.enabled_call(name, args, sc, pos, expect);
        }
        let te = self.call_expr(name, args, sc, pos, expect)?;
        let called = match &te.e {
            vm::Expr::Call(call) => Some(call.func),
            vm::Expr::CallMethod(mc) => Some(mc.call.func),
            _ => None,
        };
        if let (Ty::T(Type::Elem(Elem::Bool)), Some(func)) = (&te.ty, called) {
            if self
                .funcs
                .get(func as usize)
                .is_some_and(|f| f.ret.is_none())
            {
                return Err(self.e(
                    pos,
                    ErrorKind::TypeMismatch,
                    format!("function '{}' returns no value", name.text),
                ));
            }
        }
        Ok(te)
    }

    /// Folds an expression whose operands are all constants.
    pub(super) fn fold(&self, e: vm::Expr) -> vm::Expr {
        let e = self.fold_constants(e);
        match e {
            vm::Expr::Un(Un::NotBool, a) => match *a {
                vm::Expr::LoadAbs(s, Repr::Bool) => vm::Expr::NotAbs(s),
                other => vm::Expr::Un(Un::NotBool, Box::new(other)),
            },
            vm::Expr::Bin(op, ab) => match *ab {
                (vm::Expr::LoadAbs(x, rx), vm::Expr::LoadAbs(y, ry)) => {
                    vm::Expr::BinAbs(op, x, y, rx, ry)
                }
                (a, b) if same_bitwise_op(op, &a) => {
                    let mut operands = chain_operands(a);
                    operands.push(b);
                    vm::Expr::Chain(op, operands)
                }
                (a, vm::Expr::Const(k)) if !matches!(a, vm::Expr::Const(_)) => {
                    vm::Expr::BinK(op, Box::new(a), k)
                }
                pair => vm::Expr::Bin(op, Box::new(pair)),
            },
            other => other,
        }
    }

    pub(super) fn fold_constants(&self, e: vm::Expr) -> vm::Expr {
        let all_const = match &e {
            vm::Expr::Un(_, a) | vm::Expr::Conv(_, a) => matches!(**a, vm::Expr::Const(_)),
            vm::Expr::Bin(_, ab) => {
                matches!(ab.0, vm::Expr::Const(_)) && matches!(ab.1, vm::Expr::Const(_))
            }
            _ => false,
        };
        if !all_const {
            return e;
        }
        let mut tmp = vm::Vm {
            mem: Vec::new(),
            frame: 0,
            now: 0,
            budget: 10,
            fault: None,
            fault_at: None,
            pou: 0,
            axes: Vec::new(),
        };
        let code = Code {
            functions: Vec::new(),
            fbs: Vec::new(),
        };
        let v = tmp.eval(&code, &e);
        if tmp.fault.is_some() {
            e
        } else {
            vm::Expr::Const(v)
        }
    }

    pub(super) fn unary(&mut self, op: UnOp, te: TE, pos: Pos) -> R<TE> {
        match (op, &te.ty) {
            (UnOp::Plus, _) => Ok(te),
            (UnOp::Neg, Ty::AnyInt(v)) => Ok(TE {
                ty: Ty::AnyInt(-v),
                e: te.e,
            }),
            (UnOp::Neg, Ty::AnyReal(v)) => Ok(TE {
                ty: Ty::AnyReal(-v),
                e: te.e,
            }),
            (UnOp::Not, Ty::AnyInt(v)) => {
                // NOT of an untyped literal: take it as a DWORD-wide bit string.
                let e = self.fold(vm::Expr::Un(
                    Un::NotBits(IntKind::U32),
                    Box::new(vm::Expr::Const(*v as u64)),
                ));
                Ok(TE {
                    ty: Ty::T(Type::Elem(Elem::DWord)),
                    e,
                })
            }
            (_, Ty::T(t)) => {
                let Some(el) = t.elem() else {
                    return Err(self.e(
                        pos,
                        ErrorKind::TypeMismatch,
                        format!("operator does not apply to {}", self.type_name(t)),
                    ));
                };
                // CODESYS negates an unsigned integer or bit string in the smallest
                // signed type that holds it (-BYTE is an INT).
                if self.codesys_conversions
                    && op == UnOp::Neg
                    && (el.is_bit() || (el.is_int() && !ik(el).signed()))
                {
                    let signed = match as_unsigned(el) {
                        Elem::USInt => Elem::Int,
                        Elem::UInt => Elem::DInt,
                        _ => Elem::LInt,
                    };
                    let e = self.fold(self.convert(te.e, el, signed));
                    return Ok(TE {
                        ty: Ty::T(Type::Elem(signed)),
                        e: self.fold(vm::Expr::Un(Un::NegI(ik(signed)), Box::new(e))),
                    });
                }
                let un = match op {
                    UnOp::Neg if el.is_real() => Un::NegR(real_flag(el)),
                    UnOp::Neg if (el.is_int() && ik(el).signed()) || el == Elem::Time => {
                        Un::NegI(ik(el))
                    }
                    UnOp::Not if el == Elem::Bool => Un::NotBool,
                    UnOp::Not if el.is_bit() => Un::NotBits(ik(el)),
                    _ => {
                        let opn = if op == UnOp::Neg { "-" } else { "NOT" };
                        return Err(self.e(
                            pos,
                            ErrorKind::TypeMismatch,
                            format!("'{opn}' does not apply to {}", el.name()),
                        ));
                    }
                };
                let rt = match t {
                    Type::Subrange(e, _, _) => Type::Elem(*e),
                    t => t.clone(),
                };
                Ok(TE {
                    ty: Ty::T(rt),
                    e: self.fold(vm::Expr::Un(un, Box::new(te.e))),
                })
            }
            (UnOp::Not, Ty::AnyReal(_)) => {
                Err(self.e(pos, ErrorKind::TypeMismatch, "NOT does not apply to a real"))
            }
        }
    }

    pub(super) fn literal_fold(&self, op: BinOp, a: &Ty, b: &Ty, pos: Pos) -> R<Option<TE>> {
        let cmp = |o: std::cmp::Ordering| -> bool {
            use std::cmp::Ordering::*;
            match op {
                BinOp::Eq => o == Equal,
                BinOp::Ne => o != Equal,
                BinOp::Lt => o == Less,
                BinOp::Le => o != Greater,
                BinOp::Gt => o == Greater,
                BinOp::Ge => o != Less,
                _ => false,
            }
        };
        let is_cmp = matches!(
            op,
            BinOp::Eq | BinOp::Ne | BinOp::Lt | BinOp::Le | BinOp::Gt | BinOp::Ge
        );
        let boolean = |v: bool| TE {
            ty: Ty::T(Type::BOOL),
            e: vm::Expr::Const(v as u64),
        };
        match (a, b) {
            (Ty::AnyInt(x), Ty::AnyInt(y)) => {
                let (x, y) = (*x, *y);
                if is_cmp {
                    return Ok(Some(boolean(cmp(x.cmp(&y)))));
                }
                let v = match op {
                    BinOp::Add => x.checked_add(y),
                    BinOp::Sub => x.checked_sub(y),
                    BinOp::Mul => x.checked_mul(y),
                    BinOp::Div | BinOp::Mod if y == 0 => {
                        return Err(self.e(
                            pos,
                            ErrorKind::Invalid,
                            "division by zero in a constant expression",
                        ));
                    }
                    BinOp::Div => x.checked_div(y),
                    BinOp::Mod => x.checked_rem(y),
                    BinOp::And => Some(x & y),
                    BinOp::Or => Some(x | y),
                    BinOp::Xor => Some(x ^ y),
                    BinOp::Pow => {
                        return Ok(Some(TE {
                            ty: Ty::AnyReal((x as f64).powf(y as f64)),
                            e: vm::Expr::Const(0),
                        }));
                    }
                    _ => None,
                };
                match v.filter(|v| *v >= i64::MIN as i128 && *v <= u64::MAX as i128) {
                    Some(v) => Ok(Some(TE {
                        ty: Ty::AnyInt(v),
                        e: vm::Expr::Const(0),
                    })),
                    None => Err(self.e(pos, ErrorKind::Invalid, "constant expression overflows")),
                }
            }
            (Ty::AnyInt(_) | Ty::AnyReal(_), Ty::AnyInt(_) | Ty::AnyReal(_)) => {
                let f = |t: &Ty| match t {
                    Ty::AnyInt(v) => *v as f64,
                    Ty::AnyReal(v) => *v,
                    Ty::T(_) => 0.0,
                };
                let (x, y) = (f(a), f(b));
                if is_cmp {
                    return Ok(x.partial_cmp(&y).map(|o| boolean(cmp(o))));
                }
                let v = match op {
                    BinOp::Add => x + y,
                    BinOp::Sub => x - y,
                    BinOp::Mul => x * y,
                    BinOp::Div if y == 0.0 => {
                        return Err(self.e(
                            pos,
                            ErrorKind::Invalid,
                            "division by zero in a constant expression",
                        ));
                    }
                    BinOp::Div => x / y,
                    BinOp::Pow => x.powf(y),
                    _ => {
                        return Err(self.e(
                            pos,
                            ErrorKind::TypeMismatch,
                            "operator does not apply to reals",
                        ));
                    }
                };
                Ok(Some(TE {
                    ty: Ty::AnyReal(v),
                    e: vm::Expr::Const(0),
                }))
            }
            _ => Ok(None),
        }
    }

    /// The type two operands meet at, following the implicit widening rules.
    pub(super) fn common(&self, a: &Ty, b: &Ty, pos: Pos) -> R<Type> {
        let base = |t: &Type| match t {
            Type::Subrange(e, _, _) => Type::Elem(*e),
            t => t.clone(),
        };
        match (a, b) {
            // CODESYS types a literal that does not fit the other operand by its value:
            // INT * 60000 is computed in DINT.
            (Ty::T(x), Ty::AnyInt(v)) | (Ty::AnyInt(v), Ty::T(x))
                if self.codesys_conversions
                    && x.elem().is_some_and(|e| e.is_int() || e.is_bit())
                    && x.elem()
                        .and_then(|e| e.int_range())
                        .is_some_and(|(lo, hi)| *v < lo || *v > hi) =>
            {
                let natural = [Elem::DInt, Elem::LInt, Elem::ULInt]
                    .into_iter()
                    .find(|e| e.int_range().is_some_and(|(lo, hi)| (lo..=hi).contains(v)))
                    .unwrap_or(Elem::LInt);
                self.common(&Ty::T(base(x)), &Ty::T(Type::Elem(natural)), pos)
            }
            (Ty::T(x), Ty::AnyInt(_) | Ty::AnyReal(_)) => Ok(base(x)),
            (Ty::AnyInt(_) | Ty::AnyReal(_), Ty::T(y)) => Ok(base(y)),
            (Ty::T(x), Ty::T(y)) => {
                let (x, y) = (base(x), base(y));
                if x == y {
                    return Ok(x);
                }
                if let (Type::String(p), Type::String(q)) = (&x, &y) {
                    return Ok(Type::String((*p).max(*q)));
                }
                if let (Type::WString(p), Type::WString(q)) = (&x, &y) {
                    return Ok(Type::WString((*p).max(*q)));
                }
                // CODESYS: a bit string meets other types as the unsigned integer of its
                // width (BYTE and INT at INT).
                let goes_to = |p: Elem, q: Elem| {
                    widens(p, q)
                        || (self.codesys_conversions
                            && (q.is_int() || q.is_real())
                            && (p.is_int() || p.is_bit())
                            && widens(as_unsigned(p), as_unsigned(q)))
                };
                match (x.elem(), y.elem()) {
                    (Some(p), Some(q)) if goes_to(p, q) => Ok(y),
                    (Some(p), Some(q)) if goes_to(q, p) => Ok(x),
                    // Neither widens to the other (INT and UINT): the smallest type both
                    // widen to (DINT).
                    (Some(p), Some(q))
                        if Elem::ALL.iter().any(|t| goes_to(p, *t) && goes_to(q, *t)) =>
                    {
                        let t = Elem::ALL
                            .iter()
                            .find(|t| goes_to(p, **t) && goes_to(q, **t));
                        Ok(Type::Elem(*t.unwrap_or(&Elem::LReal)))
                    }
                    _ => Err(self.e(
                        pos,
                        ErrorKind::TypeMismatch,
                        format!(
                            "type mismatch: {} and {}",
                            self.type_name(&x),
                            self.type_name(&y)
                        ),
                    )),
                }
            }
            // Two constants the folding left alone (a non-finite value, e.g. SIN of an
            // infinity): computed in the widest type of their kind.
            (Ty::AnyReal(_), Ty::AnyReal(_) | Ty::AnyInt(_)) | (Ty::AnyInt(_), Ty::AnyReal(_)) => {
                Ok(Type::Elem(Elem::LReal))
            }
            (Ty::AnyInt(_), Ty::AnyInt(_)) => Ok(Type::Elem(Elem::LInt)),
        }
    }

    /// TIME * number and TIME / number, the number of type `rt`.
    fn scaled_time(&mut self, op: BinOp, l: TE, r: TE, rt: &Type, pos: Pos) -> R<TE> {
        let time = Type::Elem(Elem::Time);
        let re = rt.elem().unwrap_or(Elem::LInt);
        let rv = self.coerce(r, rt, pos)?;
        let bin = match (op, re.is_real()) {
            (BinOp::Mul, false) => Bin::MulTimeI,
            (BinOp::Div, false) => Bin::DivTimeI,
            (BinOp::Mul, true) => Bin::MulTimeR,
            _ => Bin::DivTimeR,
        };
        Ok(TE {
            ty: Ty::T(time),
            e: self.fold(vm::Expr::Bin(bin, Box::new((l.e, rv)))),
        })
    }

    pub(super) fn binary(&mut self, op: BinOp, l: TE, r: TE, pos: Pos) -> R<TE> {
        if let Some(te) = self.literal_fold(op, &l.ty, &r.ty, pos)? {
            return Ok(te);
        }
        if address(&l.ty) || address(&r.ty) {
            return self.address_binary(op, l, r, pos);
        }
        // TIME * number and TIME / number.
        if matches!(op, BinOp::Mul | BinOp::Div)
            && matches!(&l.ty, Ty::T(t) if t.elem() == Some(Elem::Time))
        {
            if let Some(rt) = time_factor_type(&r.ty) {
                return self.scaled_time(op, l, r, &rt, pos);
            }
        }
        if let Some(te) = self.moment_binary(op, &l, &r, pos)? {
            let (le, re) = (l.e, r.e);
            let (ty, bin, wrap_day) = te;
            let e = vm::Expr::Bin(bin, Box::new((le, re)));
            let e = if wrap_day {
                vm::Expr::Conv(Conv::DayRem, Box::new(e))
            } else {
                e
            };
            return Ok(TE {
                ty: Ty::T(Type::Elem(ty)),
                e: self.fold(e),
            });
        }
        let ct = self.common(&l.ty, &r.ty, pos)?;
        let (lt_name, rt_name) = (self.ty_name(&l.ty), self.ty_name(&r.ty));
        let le = self.coerce(l, &ct, pos)?;
        let re = self.coerce(r, &ct, pos)?;
        let mismatch = |c: &Compiler| {
            let opname = format!("{op:?}").to_uppercase();
            c.e(
                pos,
                ErrorKind::TypeMismatch,
                format!("operator {opname} does not apply to {lt_name} and {rt_name}"),
            )
        };
        let is_cmp = matches!(
            op,
            BinOp::Eq | BinOp::Ne | BinOp::Lt | BinOp::Le | BinOp::Gt | BinOp::Ge
        );
        if ct.is_string() {
            if !is_cmp {
                return Err(mismatch(self));
            }
            return Ok(string_comparison(op, &ct, le, re));
        }
        let el = match &ct {
            Type::Enum(_) => {
                if !is_cmp {
                    return Err(mismatch(self));
                }
                Elem::DInt
            }
            t => t.elem().ok_or_else(|| mismatch(self))?,
        };
        let k = ik(el);
        let s = real_flag(el);
        // CODESYS computes with bit strings as with unsigned integers of their width.
        let integer = el.is_int() || (self.codesys_conversions && el.is_bit());
        let bin = if is_cmp {
            comparison(op, el)
        } else {
            match op {
                BinOp::And | BinOp::Or | BinOp::Xor if el == Elem::Bool || el.is_bit() => {
                    match op {
                        BinOp::And => Bin::And,
                        BinOp::Or => Bin::Or,
                        _ => Bin::Xor,
                    }
                }
                BinOp::Add if integer || el == Elem::Time => Bin::AddI(k),
                BinOp::Sub if integer || el == Elem::Time => Bin::SubI(k),
                BinOp::Mul if integer => Bin::MulI(k),
                BinOp::Div if integer => Bin::DivI(k),
                BinOp::Mod if integer => Bin::ModI(k),
                BinOp::Add if el.is_real() => Bin::AddR(s),
                BinOp::Sub if el.is_real() => Bin::SubR(s),
                BinOp::Mul if el.is_real() => Bin::MulR(s),
                BinOp::Div if el.is_real() => Bin::DivR(s),
                BinOp::Pow if el.is_real() => Bin::PowR(s),
                _ => return Err(mismatch(self)),
            }
        };
        let ty = if is_cmp { Type::BOOL } else { ct };
        Ok(TE {
            ty: Ty::T(ty),
            e: self.fold(vm::Expr::Bin(bin, Box::new((le, re)))),
        })
    }

    /// TOD/DT ± TIME (a TOD wraps at midnight) and the difference of two dates, times of
    /// day or dates and times: (result type, operation, wrap to a day). Comparisons of two
    /// values of one type go the usual way (`None`).
    #[allow(clippy::type_complexity)]
    fn moment_binary(&self, op: BinOp, l: &TE, r: &TE, pos: Pos) -> R<Option<(Elem, Bin, bool)>> {
        let (Some(a), Some(b)) = (elem_of(&l.ty), elem_of(&r.ty)) else {
            return Ok(None);
        };
        if !a.is_moment() && !b.is_moment() {
            return Ok(None);
        }
        let k = IntKind::I64;
        Ok(Some(match (op, a, b) {
            (BinOp::Add | BinOp::Sub, Elem::Tod | Elem::Dt, Elem::Time) => {
                let bin = if op == BinOp::Add {
                    Bin::AddI(k)
                } else {
                    Bin::SubI(k)
                };
                (a, bin, a == Elem::Tod)
            }
            (BinOp::Sub, x, y) if x == y => (Elem::Time, Bin::SubI(k), false),
            (BinOp::Eq | BinOp::Ne | BinOp::Lt | BinOp::Le | BinOp::Gt | BinOp::Ge, x, y)
                if x == y =>
            {
                return Ok(None);
            }
            _ => {
                return Err(self.e(
                    pos,
                    ErrorKind::TypeMismatch,
                    format!(
                        "operator {} does not apply to {} and {} (TOD and DT take + and - of a TIME; two of one type subtract to a TIME)",
                        format!("{op:?}").to_uppercase(),
                        a.name(),
                        b.name()
                    ),
                ));
            }
        }))
    }

    /// Operators on pointers and interfaces: comparison with each other or with 0, and
    /// pointer ± integer (in bytes).
    fn address_binary(&mut self, op: BinOp, l: TE, r: TE, pos: Pos) -> R<TE> {
        let message = format!(
            "operator {} does not apply to {} and {}",
            format!("{op:?}").to_uppercase(),
            self.ty_name(&l.ty),
            self.ty_name(&r.ty)
        );
        let mismatch = |c: &Compiler| c.e(pos, ErrorKind::TypeMismatch, message.clone());
        let raw = |c: &Compiler, t: TE| -> R<vm::Expr> {
            match t.ty {
                Ty::AnyInt(v) if (0..=u64::MAX as i128).contains(&v) => {
                    Ok(vm::Expr::Const(v as u64))
                }
                Ty::T(ref x) if x.is_address() => Ok(t.e),
                Ty::T(ref x) if x.elem().is_some_and(|e| e.is_int() || e.is_bit()) => {
                    let e = x.elem().unwrap_or(Elem::LWord);
                    Ok(c.fold(c.convert(t.e, e, Elem::LInt)))
                }
                _ => Err(mismatch(c)),
            }
        };
        match op {
            BinOp::Eq | BinOp::Ne | BinOp::Lt | BinOp::Le | BinOp::Gt | BinOp::Ge => {
                let bin = match op {
                    BinOp::Eq => Bin::Eq,
                    BinOp::Ne => Bin::Ne,
                    BinOp::Lt => Bin::Lt(false),
                    BinOp::Le => Bin::Le(false),
                    BinOp::Gt => Bin::Gt(false),
                    _ => Bin::Ge(false),
                };
                let le = raw(self, l)?;
                let re = raw(self, r)?;
                Ok(TE {
                    ty: Ty::T(Type::BOOL),
                    e: self.fold(vm::Expr::Bin(bin, Box::new((le, re)))),
                })
            }
            BinOp::Add | BinOp::Sub
                if matches!(&l.ty, Ty::T(Type::Pointer(_))) && !address(&r.ty) =>
            {
                let ty = l.ty.clone();
                let bin = if op == BinOp::Add {
                    Bin::AddI(IntKind::U64)
                } else {
                    Bin::SubI(IntKind::U64)
                };
                let le = raw(self, l)?;
                let re = raw(self, r)?;
                Ok(TE {
                    ty,
                    e: self.fold(vm::Expr::Bin(bin, Box::new((le, re)))),
                })
            }
            _ => Err(mismatch(self)),
        }
    }

    /// Converts an expression to type `to` if IEC allows it implicitly.
    pub(super) fn coerce(&self, te: TE, to: &Type, pos: Pos) -> R<vm::Expr> {
        let mismatch = |c: &Compiler, from: &Ty| {
            c.e(pos, ErrorKind::TypeMismatch, {
                let from = c.ty_name(from);
                let article = if from.starts_with(['A', 'E', 'I', 'O', 'a', 'e', 'i', 'o', 'u']) {
                    "an"
                } else {
                    "a"
                };
                let to_name = c.type_name(to);
                // A bare number where a duration goes: say how to write one.
                let hint = if to_name == "TIME" && from.ends_with("literal") {
                    " (write a duration as T#5ms)"
                } else {
                    ""
                };
                format!("type mismatch: {article} {from} value where {to_name} is expected{hint}")
            })
        };
        match &te.ty {
            Ty::AnyInt(v) => {
                let v = *v;
                let Some(el) = to.scalar() else {
                    return Err(mismatch(self, &te.ty));
                };
                if matches!(to, Type::Enum(_)) {
                    return Err(mismatch(self, &te.ty));
                }
                if el.is_real() {
                    let f = v as f64;
                    return Ok(vm::Expr::Const(if el == Elem::Real {
                        ((f as f32) as f64).to_bits()
                    } else {
                        f.to_bits()
                    }));
                }
                if el == Elem::Time {
                    return Err(mismatch(self, &te.ty));
                }
                let (lo, hi) = match to {
                    Type::Subrange(_, l, h) => (*l as i128, *h as i128),
                    _ => el.int_range().unwrap_or((0, 1)),
                };
                if v < lo || v > hi {
                    return Err(self.e(
                        pos,
                        ErrorKind::TypeMismatch,
                        format!("{v} does not fit {}", self.type_name(to)),
                    ));
                }
                Ok(vm::Expr::Const(v as i64 as u64))
            }
            Ty::AnyReal(f) => match to.elem() {
                Some(Elem::Real) => Ok(vm::Expr::Const(((*f as f32) as f64).to_bits())),
                Some(Elem::LReal) => Ok(vm::Expr::Const(f.to_bits())),
                _ => Err(mismatch(self, &te.ty)),
            },
            Ty::T(from) => {
                if from == to {
                    return Ok(te.e);
                }
                match (from, to) {
                    (Type::String(_), Type::String(_)) | (Type::WString(_), Type::WString(_)) => {
                        return Ok(te.e);
                    }
                    (Type::Subrange(a, _, _), Type::Subrange(b, _, _)) if a == b => return Ok(te.e),
                    (Type::Fb(x), Type::Interface(i)) if self.fb_implements(*x, *i) => {
                        // The interface holds the instance's byte address.
                        if let vm::Expr::AddrOf(p) = te.e {
                            return Ok(vm::Expr::RefOf(p));
                        }
                        return Err(mismatch(self, &te.ty));
                    }
                    (Type::Interface(j), Type::Interface(i)) if self.iface_extends(*j, *i) => {
                        return Ok(te.e);
                    }
                    // A POINTER TO BYTE takes any pointer and goes to any: it walks the
                    // bytes of what it points to, laid out as in CODESYS.
                    (Type::Pointer(a), Type::Pointer(b))
                        if a == b
                            || matches!(**a, Type::Elem(Elem::Byte))
                            || matches!(**b, Type::Elem(Elem::Byte))
                            || matches!((&**a, &**b), (Type::Fb(x), Type::Fb(y)) if self.fb_extends(*x, *y)) =>
                    {
                        return Ok(te.e);
                    }
                    // CODESYS and TwinCAT take pointers to and from 64-bit words.
                    (Type::Pointer(_), Type::Elem(Elem::LWord | Elem::ULInt))
                    | (Type::Elem(Elem::LWord | Elem::ULInt), Type::Pointer(_)) => {
                        return Ok(te.e);
                    }
                    // CODESYS 2.3's addresses are 32-bit words (addresses here are small
                    // enough to fit one).
                    (Type::Pointer(_), Type::Elem(Elem::DWord | Elem::UDInt))
                    | (Type::Elem(Elem::DWord | Elem::UDInt), Type::Pointer(_))
                        if self.codesys_conversions =>
                    {
                        return Ok(te.e);
                    }
                    // CODESYS's ADR gives an untyped address, which any pointer takes: a
                    // POINTER TO DWORD reads a REAL's bits, a POINTER TO ARRAY[1..255] OF
                    // BYTE a STRING's characters.
                    (Type::Pointer(_), Type::Pointer(_)) if self.codesys_conversions => {
                        return Ok(te.e);
                    }
                    _ => {}
                }
                let (Some(f), Some(t)) = (from.elem(), to.elem()) else {
                    return Err(mismatch(self, &te.ty));
                };
                let converts = if self.codesys_conversions {
                    codesys_converts(f, t)
                } else {
                    widens(f, t)
                };
                if !converts {
                    return Err(mismatch(self, &te.ty));
                }
                Ok(self.fold(self.convert(te.e, f, t)))
            }
        }
    }

    /// Builds the conversion of a value from `f` to `t` (any pair of elementary types).
    pub(super) fn convert(&self, e: vm::Expr, f: Elem, t: Elem) -> vm::Expr {
        let c = |cv: Conv, e: vm::Expr| vm::Expr::Conv(cv, Box::new(e));
        if f == t {
            return e;
        }
        if f.is_moment() || t.is_moment() {
            return crate::dates::convert(e, f, t).unwrap_or(vm::Expr::Const(0));
        }
        match (f, t) {
            (_, Elem::Bool) if f.is_real() => c(Conv::RealToBool, e),
            (_, Elem::Bool) => c(Conv::IntToBool, e),
            (Elem::Time, t) if t.is_real() => c(Conv::NsToRealMs(real_flag(t)), e),
            (Elem::Time, t) => c(Conv::Int(ik(t)), c(Conv::NsToMs, e)),
            (f, Elem::Time) if f.is_real() => c(Conv::RealMsToNs, e),
            (_, Elem::Time) => c(Conv::MsToNs, e),
            (f, t) if f.is_real() && t.is_real() => {
                if t == Elem::Real {
                    c(Conv::ToF32, e)
                } else {
                    e
                }
            }
            (f, t) if f.is_real() => c(Conv::RealToInt(ik(t)), e),
            (f, t) if t.is_real() => c(
                Conv::IntToReal {
                    signed: ik(f).signed(),
                    f32: real_flag(t),
                },
                e,
            ),
            (_, t) => {
                // Integer to integer: a no-op when every value of f fits t's encoding.
                let (fl, fh) = ik(f).range();
                let (tl, th) = ik(t).range();
                if fl >= tl && fh <= th {
                    e
                } else {
                    c(Conv::Int(ik(t)), e)
                }
            }
        }
    }
}

/// The type a TIME is multiplied or divided by: a number's.
fn time_factor_type(ty: &Ty) -> Option<Type> {
    match ty {
        Ty::AnyInt(_) => Some(Type::Elem(Elem::LInt)),
        Ty::AnyReal(_) => Some(Type::Elem(Elem::LReal)),
        Ty::T(t) if t.elem().is_some_and(|e| e.is_num()) => Some(t.clone()),
        _ => None,
    }
}

/// A comparison `op` of two strings (`ct`: STRING or WSTRING).
fn string_comparison(op: BinOp, ct: &Type, le: vm::Expr, re: vm::Expr) -> TE {
    use std::cmp::Ordering::*;
    let w = matches!(ct, Type::WString(_));
    let (bin, swap_not) = match op {
        BinOp::Eq => (Bin::CmpS(Equal, false, w), false),
        BinOp::Ne => (Bin::CmpS(Equal, false, w), true),
        BinOp::Lt => (Bin::CmpS(Less, false, w), false),
        BinOp::Le => (Bin::CmpS(Less, true, w), false),
        BinOp::Gt => (Bin::CmpS(Greater, false, w), false),
        _ => (Bin::CmpS(Greater, true, w), false),
    };
    let e = vm::Expr::Bin(bin, Box::new((le, re)));
    let e = if swap_not {
        vm::Expr::Un(Un::NotBool, Box::new(e))
    } else {
        e
    };
    TE {
        ty: Ty::T(Type::BOOL),
        e,
    }
}

/// True when `op` is AND, OR or XOR and `e` is a node of that same operator, which `e op
/// x` then extends into one [`vm::Expr::Chain`] (the operators are associative, and the
/// chain keeps the operands' order of evaluation).
fn same_bitwise_op(op: Bin, e: &vm::Expr) -> bool {
    let inner = match e {
        vm::Expr::Bin(inner, _)
        | vm::Expr::BinAbs(inner, ..)
        | vm::Expr::BinK(inner, ..)
        | vm::Expr::Chain(inner, _) => *inner,
        _ => return false,
    };
    matches!(
        (op, inner),
        (Bin::And, Bin::And) | (Bin::Or, Bin::Or) | (Bin::Xor, Bin::Xor)
    )
}

/// The operands of a binary node or chain, in order of evaluation.
fn chain_operands(e: vm::Expr) -> Vec<vm::Expr> {
    match e {
        vm::Expr::Chain(_, operands) => operands,
        vm::Expr::Bin(_, ab) => {
            let (a, b) = *ab;
            vec![a, b]
        }
        vm::Expr::BinAbs(_, x, y, rx, ry) => {
            vec![vm::Expr::LoadAbs(x, rx), vm::Expr::LoadAbs(y, ry)]
        }
        vm::Expr::BinK(_, a, k) => vec![*a, vm::Expr::Const(k)],
        other => vec![other],
    }
}

/// The comparison `op` of two numbers, times or bit strings of type `el`.
fn comparison(op: BinOp, el: Elem) -> Bin {
    if el.is_real() {
        match op {
            BinOp::Eq => Bin::EqR,
            BinOp::Ne => Bin::NeR,
            BinOp::Lt => Bin::LtR,
            BinOp::Le => Bin::LeR,
            BinOp::Gt => Bin::GtR,
            _ => Bin::GeR,
        }
    } else {
        let sg = ik(el).signed();
        match op {
            BinOp::Eq => Bin::Eq,
            BinOp::Ne => Bin::Ne,
            BinOp::Lt => Bin::Lt(sg),
            BinOp::Le => Bin::Le(sg),
            BinOp::Gt => Bin::Gt(sg),
            _ => Bin::Ge(sg),
        }
    }
}
