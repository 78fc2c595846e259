//! Statements.

use super::*;

impl<'a> Compiler<'a> {
    // ---------------------------------------------------------------- statements

    pub(super) fn block(&mut self, stmts: &[ast::Stmt], sc: &mut Scope) -> R<Block> {
        let mut out = Vec::with_capacity(stmts.len());
        for s in stmts {
            match self.stmt(s, sc) {
                Ok(Some(s)) => out.push(s),
                Ok(None) => {}
                Err(e) => self.errors.push(e),
            }
        }
        Ok(out.into_boxed_slice())
    }

    pub(super) fn cond(&mut self, e: &AExpr, sc: &mut Scope) -> R<vm::Expr> {
        let te = self.expr(e, sc, Some(&Type::BOOL))?;
        self.coerce(te, &Type::BOOL, e.pos())
    }

    pub(super) fn stmt(&mut self, s: &ast::Stmt, sc: &mut Scope) -> R<Option<Stmt>> {
        let (line, kind) = match s {
            ast::Stmt::Empty => return Ok(None),
            ast::Stmt::Assign(target, value, pos) => {
                (pos.line, self.assign(target, value, sc, *pos)?)
            }
            ast::Stmt::RefAssign(target, value, pos) => {
                (pos.line, self.ref_assign(target, value, sc)?)
            }
            ast::Stmt::Call(target, args, pos) => {
                let is = |a: &Arg, n: &str| match a {
                    Arg::Input(x, _) | Arg::Output(x, _, _) => x.text == n,
                    Arg::Positional(_) => false,
                };
                if args.iter().any(|a| is(a, "EN") || is(a, "ENO")) {
                    return self.call_with_en(target, args, sc, *pos).map(Some);
                }
                (pos.line, self.call_stmt(target, args, sc, *pos)?)
            }
            ast::Stmt::If(branches, els, pos) => (pos.line, self.if_stmt(branches, els, sc)?),
            ast::Stmt::Case(sel, arms, els, pos) => (pos.line, self.case_stmt(sel, arms, els, sc)?),
            ast::Stmt::For {
                var,
                from,
                to,
                by,
                body,
                pos,
            } => (
                pos.line,
                self.for_stmt(var, from, to, by.as_ref(), body, sc)?,
            ),
            ast::Stmt::While(c, body, pos) => {
                let c = self.cond(c, sc)?;
                sc.loops += 1;
                let b = self.block(body, sc);
                sc.loops -= 1;
                (pos.line, StmtKind::While(c, b?))
            }
            ast::Stmt::Repeat(body, c, pos) => {
                sc.loops += 1;
                let b = self.block(body, sc);
                sc.loops -= 1;
                let c = self.cond(c, sc)?;
                (pos.line, StmtKind::Repeat(b?, c))
            }
            ast::Stmt::Exit(pos) | ast::Stmt::Continue(pos) => {
                if sc.loops == 0 {
                    return Err(self.e(
                        *pos,
                        ErrorKind::Invalid,
                        "EXIT and CONTINUE belong inside a loop",
                    ));
                }
                (
                    pos.line,
                    if matches!(s, ast::Stmt::Exit(_)) {
                        StmtKind::Exit
                    } else {
                        StmtKind::Continue
                    },
                )
            }
            ast::Stmt::Return(pos) => (pos.line, StmtKind::Return),
        };
        Ok(Some(Stmt { line, kind }))
    }

    fn if_stmt(
        &mut self,
        branches: &[(AExpr, Vec<ast::Stmt>)],
        els: &[ast::Stmt],
        sc: &mut Scope,
    ) -> R<StmtKind> {
        let mut bs = Vec::new();
        for (c, b) in branches {
            let c = self.cond(c, sc)?;
            bs.push((c, self.block(b, sc)?));
        }
        Ok(StmtKind::If(bs.into_boxed_slice(), self.block(els, sc)?))
    }

    fn case_stmt(
        &mut self,
        sel: &AExpr,
        arms: &[ast::CaseArm],
        els: &[ast::Stmt],
        sc: &mut Scope,
    ) -> R<StmtKind> {
        let te = self.expr(sel, sc, None)?;
        let sel_ty = match &te.ty {
            Ty::T(t)
                if t.scalar().is_some_and(|e| {
                    e.int_kind().is_some() && e != Elem::Time && e != Elem::Bool
                }) =>
            {
                t.clone()
            }
            Ty::AnyInt(_) => Type::Elem(Elem::DInt),
            _ => {
                return Err(self.e(
                    sel.pos(),
                    ErrorKind::TypeMismatch,
                    "CASE needs an integer or enumeration selector",
                ));
            }
        };
        let signed =
            matches!(sel_ty, Type::Enum(_)) || sel_ty.scalar().is_some_and(|e| ik(e).signed());
        let selector = self.coerce(te, &sel_ty, sel.pos())?;
        let mut out = Vec::new();
        let mut seen: Vec<(i64, i64)> = Vec::new();
        for arm in arms {
            let ranges = self.case_ranges(arm, &sel_ty, &seen, sc)?;
            seen.extend(ranges.iter().copied());
            out.push(CaseArm {
                ranges: ranges.into_boxed_slice(),
                body: self.block(&arm.body, sc)?,
            });
        }
        Ok(StmtKind::Case {
            selector,
            signed,
            arms: out.into_boxed_slice(),
            default: self.block(els, sc)?,
        })
    }

    /// The value ranges of a CASE arm's labels, none of which may overlap another label of
    /// the arm or one of the earlier arms' (`seen`).
    fn case_ranges(
        &mut self,
        arm: &ast::CaseArm,
        sel_ty: &Type,
        seen: &[(i64, i64)],
        sc: &mut Scope,
    ) -> R<Vec<(i64, i64)>> {
        let mut ranges = Vec::new();
        for (lo, hi) in &arm.labels {
            let l = self.case_label(lo, sel_ty, sc)?;
            let h = match hi {
                Some(h) => self.case_label(h, sel_ty, sc)?,
                None => l,
            };
            if h < l {
                return Err(self.e(lo.pos(), ErrorKind::Invalid, "empty CASE range"));
            }
            let clash = seen
                .iter()
                .chain(ranges.iter())
                .find(|(a, b)| l <= *b && *a <= h);
            if let Some((a, b)) = clash {
                let shown = if a == b {
                    a.to_string()
                } else {
                    format!("{a}..{b}")
                };
                return Err(self.e(
                    lo.pos(),
                    ErrorKind::Invalid,
                    format!("CASE label overlaps the earlier label {shown}"),
                ));
            }
            ranges.push((l, h));
        }
        Ok(ranges)
    }

    fn for_stmt(
        &mut self,
        var: &Name,
        from: &AExpr,
        to: &AExpr,
        by: Option<&AExpr>,
        body: &[ast::Stmt],
        sc: &mut Scope,
    ) -> R<StmtKind> {
        let a = Access {
            root: var.clone(),
            parts: Vec::new(),
        };
        if sc.for_vars.contains(&var.text) {
            return Err(self.e(
                var.pos,
                ErrorKind::Invalid,
                format!(
                    "'{}' is already the control variable of an enclosing FOR loop",
                    var.text
                ),
            ));
        }
        let lv = self.access(&a, sc)?;
        self.check_writable(&lv, var.pos)?;
        let Some(e) = lv.ty.elem().filter(|e| e.is_int()) else {
            return Err(self.e(
                var.pos,
                ErrorKind::TypeMismatch,
                "FOR needs an integer control variable",
            ));
        };
        let t = Type::Elem(e);
        let f = self.expr(from, sc, Some(&t))?;
        let from_e = self.coerce(f, &t, from.pos())?;
        let tt = self.expr(to, sc, Some(&t))?;
        let to_e = self.coerce(tt, &t, to.pos())?;
        let by_e = match by {
            Some(b) => {
                let te = self.expr(b, sc, Some(&t))?;
                self.coerce(te, &t, b.pos())?
            }
            None => vm::Expr::Const(1),
        };
        sc.loops += 1;
        sc.for_vars.push(var.text.clone());
        let body = self.block(body, sc);
        sc.for_vars.pop();
        sc.loops -= 1;
        let var_place = self.place(lv);
        Ok(StmtKind::For(Box::new(ForLoop {
            var: var_place,
            repr: Repr::of(e),
            kind: ik(e),
            from: from_e,
            to: to_e,
            by: by_e,
            body: body?,
        })))
    }

    /// A call with `EN := c` and/or `ENO => v`: the call runs only while EN is TRUE, and
    /// ENO tells whether it ran (no call here ends with an error).
    fn call_with_en(&mut self, target: &Access, args: &[Arg], sc: &mut Scope, pos: Pos) -> R<Stmt> {
        let mut en = None;
        let mut eno = None;
        let mut rest = Vec::new();
        for a in args {
            match a {
                Arg::Input(n, e) if n.text == "EN" => en = Some(e),
                Arg::Output(n, t, neg) if n.text == "ENO" => eno = Some((t, *neg, n.pos)),
                Arg::Input(n, _) if n.text == "ENO" => {
                    return Err(self.e(
                        n.pos,
                        ErrorKind::WrongArgument,
                        "ENO is an output: write ENO => variable",
                    ));
                }
                a => rest.push(a.clone()),
            }
        }
        let call = Stmt {
            line: pos.line,
            kind: self.call_stmt(target, &rest, sc, pos)?,
        };
        let cond = match en {
            Some(e) => self.cond(e, sc)?,
            None => vm::Expr::Const(1),
        };
        let mut eno_store = |c: &mut Self, v: u64| -> R<Option<Stmt>> {
            let Some((Some(t), neg, _)) = &eno else {
                return Ok(None);
            };
            let lv = c.access(t, sc)?;
            c.check_writable(&lv, t.root.pos)?;
            if !lv.ty.is_bool() && lv.bit.is_none() {
                return Err(c.e(t.root.pos, ErrorKind::WrongArgument, "ENO goes to a BOOL"));
            }
            let v = if *neg { v ^ 1 } else { v };
            let r = repr_of(&lv.ty);
            let kind = match lv.bit {
                Some(b) => StmtKind::StoreBit(c.place(lv), r, b, vm::Expr::Const(v)),
                None => StmtKind::Store(c.place(lv), vm::Expr::Const(v), Store::Scalar(r)),
            };
            Ok(Some(Stmt {
                line: pos.line,
                kind,
            }))
        };
        let mut then = vec![call];
        then.extend(eno_store(self, 1)?);
        let otherwise: Vec<Stmt> = eno_store(self, 0)?.into_iter().collect();
        Ok(Stmt {
            line: pos.line,
            kind: StmtKind::If(
                vec![(cond, then.into_boxed_slice())].into_boxed_slice(),
                otherwise.into_boxed_slice(),
            ),
        })
    }

    pub(super) fn case_label(&mut self, e: &AExpr, t: &Type, sc: &mut Scope) -> R<i64> {
        let te = self.expr(e, sc, Some(t))?;
        match self.coerce(te, t, e.pos())? {
            vm::Expr::Const(v) => Ok(v as i64),
            _ => Err(self.e(e.pos(), ErrorKind::Invalid, "CASE labels must be constants")),
        }
    }

    pub(super) fn store_kind(&self, t: &Type) -> Store {
        match t {
            Type::Subrange(e, l, h) => Store::Range(*l, *h, Repr::of(*e)),
            Type::String(n) => Store::String(*n, false),
            Type::WString(n) => Store::String(*n, true),
            t if t.scalar().is_some() => Store::Scalar(repr_of(t)),
            t => Store::Block(size_of(self, t)),
        }
    }

    pub(super) fn assign(
        &mut self,
        target: &Access,
        value: &AExpr,
        sc: &mut Scope,
        pos: Pos,
    ) -> R<StmtKind> {
        if target.parts.is_empty() && sc.for_vars.contains(&target.root.text) {
            return Err(self.e(
                target.root.pos,
                ErrorKind::Invalid,
                format!(
                    "'{}' is the control variable of an enclosing FOR loop",
                    target.root.text
                ),
            ));
        }
        if let Some((r, p)) = self.property_of(target, sc)? {
            let arg = Arg::Input(p.clone(), value.clone());
            let te = self.invoke(r, &p, Invoke::Set, &[arg], sc, pos)?;
            return Ok(StmtKind::Eval(te.e));
        }
        let lv = self.access(target, sc)?;
        self.check_writable(&lv, target.root.pos)?;
        if let Type::Fb(_) = lv.ty {
            return Err(self.e(
                pos,
                ErrorKind::TypeMismatch,
                "function block instances cannot be assigned",
            ));
        }
        let te = self.expr(value, sc, Some(&lv.ty))?;
        if let Some(bit) = lv.bit {
            let v = self.coerce(te, &Type::BOOL, value.pos())?;
            let r = repr_of(&lv.ty);
            let p = self.place(lv);
            return Ok(StmtKind::StoreBit(p, r, bit, v));
        }
        let ty = lv.ty.clone();
        let v = self.coerce(te, &ty, value.pos())?;
        if let (Type::Subrange(_, l, h), vm::Expr::Const(c)) = (&ty, &v) {
            let x = *c as i64;
            if x < *l || x > *h {
                return Err(self.e(
                    value.pos(),
                    ErrorKind::TypeMismatch,
                    format!("{x} is outside the subrange {l}..{h}"),
                ));
            }
        }
        let st = self.store_kind(&ty);
        let p = self.place(lv);
        Ok(StmtKind::Store(p, v, st))
    }

    pub(super) fn check_writable(&mut self, lv: &Lv, pos: Pos) -> R<()> {
        match &lv.readonly {
            None => {
                if let Some(w) = &lv.warn_on_write {
                    let message = self.respell(w);
                    self.warnings.push(Warning {
                        file: self.file.to_string(),
                        pos,
                        code: ErrorKind::AssignToInput.code(),
                        message,
                    });
                }
                Ok(())
            }
            Some((k, m)) => Err(self.e(pos, *k, m.clone())),
        }
    }

    /// `r REF= x`: `r` (a REFERENCE TO T) now points at `x` (of type T), or at nothing
    /// for `REF= 0`.
    pub(super) fn ref_assign(
        &mut self,
        target: &Access,
        value: &AExpr,
        sc: &mut Scope,
    ) -> R<StmtKind> {
        let lv = self.access_opt(target, sc, true)?;
        let Type::Reference(t) = lv.ty.clone() else {
            return Err(self.e(
                target.root.pos,
                ErrorKind::TypeMismatch,
                format!(
                    "REF= needs a REFERENCE on its left; '{}' is {}",
                    target.root.text,
                    self.type_name(&lv.ty)
                ),
            ));
        };
        self.check_writable(&lv, target.root.pos)?;
        let v = match value {
            AExpr::Lit(Literal::Int(0), _) => vm::Expr::Const(0),
            AExpr::Var(a) => {
                let x = self.access(a, sc)?;
                if !self.same_or_derived(&x.ty, &t) || x.bit.is_some() {
                    return Err(self.e(
                        value.pos(),
                        ErrorKind::TypeMismatch,
                        format!(
                            "a REFERENCE TO {} cannot refer to a {}",
                            self.type_name(&t),
                            self.type_name(&x.ty)
                        ),
                    ));
                }
                vm::Expr::RefOf(self.place(x))
            }
            _ => {
                return Err(self.e(
                    value.pos(),
                    ErrorKind::Invalid,
                    "REF= needs a variable on its right (or 0)",
                ));
            }
        };
        Ok(StmtKind::Store(self.place(lv), v, Store::Scalar(Repr::U64)))
    }

    /// May a variable of type `from` be referred to where `to` is expected: the same
    /// type, or a function block derived from `to`.
    pub(super) fn same_or_derived(&self, from: &Type, to: &Type) -> bool {
        match (from, to) {
            (Type::Fb(a), Type::Fb(b)) => self.fb_extends(*a, *b),
            (a, b) => a == b,
        }
    }
}

impl Compiler<'_> {
    /// `F(EN := c, ..., ENO => v)` inside an expression: the function runs only while c is
    /// TRUE; its value is then the function's, else 0 (IEC 61131-3 leaves it to the
    /// implementation), and ENO tells whether it ran. Only for elementary results.
    pub(super) fn enabled_call(
        &mut self,
        name: &Name,
        args: &[Arg],
        sc: &mut Scope,
        pos: Pos,
        expect: Option<&Type>,
    ) -> R<TE> {
        let mut en = None;
        let mut eno = None;
        let mut rest = Vec::new();
        for a in args {
            match a {
                Arg::Input(n, e) if n.text == "EN" => en = Some(e),
                Arg::Output(n, t, neg) if n.text == "ENO" => eno = Some((t, *neg)),
                Arg::Input(n, _) if n.text == "ENO" => {
                    return Err(self.e(
                        n.pos,
                        ErrorKind::WrongArgument,
                        "ENO is an output: write ENO => variable",
                    ));
                }
                a => rest.push(a.clone()),
            }
        }
        let te = self.call_expr(name, &rest, sc, pos, expect)?;
        let ty = match te.ty {
            Ty::T(t) if t.scalar().is_some() && !t.is_string() => t,
            _ => {
                return Err(self.e(
                    pos,
                    ErrorKind::WrongArgument,
                    format!(
                        "EN/ENO inside an expression needs a function with an elementary \
                         result and a variable operand; call {} as a statement with EN/ENO \
                         instead",
                        name.text
                    ),
                ));
            }
        };
        if let vm::Expr::Call(call) = &te.e {
            if self
                .funcs
                .get(call.func as usize)
                .is_some_and(|f| f.ret.is_none())
            {
                return Err(self.e(
                    pos,
                    ErrorKind::TypeMismatch,
                    format!("function '{}' returns no value", name.text),
                ));
            }
        }
        let en = match en {
            Some(e) => self.cond(e, sc)?,
            None => vm::Expr::Const(1),
        };
        let eno = match eno {
            Some((Some(t), negate)) => {
                let lv = self.access(t, sc)?;
                self.check_writable(&lv, t.root.pos)?;
                if !lv.ty.is_bool() && lv.bit.is_none() {
                    return Err(self.e(t.root.pos, ErrorKind::WrongArgument, "ENO goes to a BOOL"));
                }
                let bit = lv.bit;
                let r = repr_of(&lv.ty);
                Some((self.place(lv), r, bit, negate))
            }
            _ => None,
        };
        Ok(TE {
            ty: Ty::T(ty),
            e: vm::Expr::Enabled(Box::new(vm::EnabledCall {
                en,
                call: te.e,
                eno,
            })),
        })
    }
}
