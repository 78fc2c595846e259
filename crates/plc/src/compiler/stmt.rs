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
            ast::Stmt::Call(target, args, pos) => {
                (pos.line, self.call_stmt(target, args, sc, *pos)?)
            }
            ast::Stmt::If(branches, els, pos) => {
                let mut bs = Vec::new();
                for (c, b) in branches {
                    let c = self.cond(c, sc)?;
                    bs.push((c, self.block(b, sc)?));
                }
                (
                    pos.line,
                    StmtKind::If(bs.into_boxed_slice(), self.block(els, sc)?),
                )
            }
            ast::Stmt::Case(sel, arms, els, pos) => {
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
                let signed = matches!(sel_ty, Type::Enum(_))
                    || sel_ty.scalar().is_some_and(|e| ik(e).signed());
                let selector = self.coerce(te, &sel_ty, sel.pos())?;
                let mut out = Vec::new();
                let mut seen: Vec<(i64, i64)> = Vec::new();
                for arm in arms {
                    let mut ranges = Vec::new();
                    for (lo, hi) in &arm.labels {
                        let l = self.case_label(lo, &sel_ty, sc)?;
                        let h = match hi {
                            Some(h) => self.case_label(h, &sel_ty, sc)?,
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
                    seen.extend(ranges.iter().copied());
                    out.push(CaseArm {
                        ranges: ranges.into_boxed_slice(),
                        body: self.block(&arm.body, sc)?,
                    });
                }
                (
                    pos.line,
                    StmtKind::Case {
                        selector,
                        signed,
                        arms: out.into_boxed_slice(),
                        default: self.block(els, sc)?,
                    },
                )
            }
            ast::Stmt::For {
                var,
                from,
                to,
                by,
                body,
                pos,
            } => {
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
                (
                    pos.line,
                    StmtKind::For(Box::new(ForLoop {
                        var: var_place,
                        kind: ik(e),
                        from: from_e,
                        to: to_e,
                        by: by_e,
                        body: body?,
                    })),
                )
            }
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

    pub(super) fn case_label(&mut self, e: &AExpr, t: &Type, sc: &mut Scope) -> R<i64> {
        let te = self.expr(e, sc, Some(t))?;
        match self.coerce(te, t, e.pos())? {
            vm::Expr::Const(v) => Ok(v as i64),
            _ => Err(self.e(e.pos(), ErrorKind::Invalid, "CASE labels must be constants")),
        }
    }

    pub(super) fn store_kind(&self, t: &Type) -> Store {
        match t {
            Type::Subrange(_, l, h) => Store::Range(*l, *h),
            Type::String(n) => Store::String(*n),
            t if t.scalar().is_some() => Store::Scalar,
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
            let p = self.place(lv);
            return Ok(StmtKind::StoreBit(p, bit, v));
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

    pub(super) fn check_writable(&self, lv: &Lv, pos: Pos) -> R<()> {
        match &lv.readonly {
            None => Ok(()),
            Some((k, m)) => Err(self.e(pos, *k, m.clone())),
        }
    }
}
