//! A move's geometry built apart from the planner, so that a caller sharing the planner with
//! a faster task (the kernel's look-ahead and interpolation) holds it only to copy and to
//! append. Building is the costly part of a push (a blend's trim search, smoothing, the
//! pieces' sampling: up to a few milliseconds in an unoptimised build); appending joins the
//! pieces to the window and updates the braking curve.
//!
//! [`Planner::prepare`] copies the planner's geometry state into a [`PreparedMove`],
//! [`PreparedMove::build`] feeds the move through the copy without the planner, and
//! [`Planner::push_prepared`] appends the result if the planner's geometry has not changed
//! since the copy (no other push, flush, stop or reset): the result is then the same as
//! [`Planner::push`] of the move.

use super::*;

/// A move being built apart from the planner (see the module documentation). Memory is
/// taken once, at creation.
pub struct PreparedMove {
    builder: Builder,
    lim: Lim,
    /// The planner's geometry generation the copy was taken at.
    generation: u64,
    /// The caller's number for the move.
    key: u64,
    mv: Option<Move>,
    result: Option<Result<(), MotionError>>,
    pieces: Vec<Piece>,
}

/// Where a [`PreparedMove`] stands for a move.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Preparation {
    /// Not taken for this move, or taken before the planner's geometry changed: call
    /// [`Planner::prepare`].
    Stale,
    /// Taken by [`Planner::prepare`]; [`PreparedMove::build`] is due.
    Copied,
    /// Built: [`Planner::push_prepared`] appends it.
    Built,
}

impl Default for PreparedMove {
    fn default() -> Self {
        Self::new()
    }
}

impl PreparedMove {
    /// Empty, with room for the pieces of one move.
    ///
    /// Real-time: no (set-up: allocates).
    pub fn new() -> PreparedMove {
        PreparedMove {
            builder: Builder::new([0.0; AXES]),
            lim: Lim::from(&MachineLimits { axes: [None; AXES] }),
            generation: u64::MAX,
            key: 0,
            mv: None,
            result: None,
            pieces: Vec::with_capacity(PIECES_PER_MOVE + FLUSH_PIECES),
        }
    }

    /// Feeds the move through the copied geometry state (the costly part of a push),
    /// without the planner. Nothing to do unless [`Planner::prepare`] copied since the last
    /// build.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn build(&mut self) {
        let (Some(mv), true) = (self.mv, self.result.is_none()) else {
            return;
        };
        self.pieces.clear();
        let result = self.builder.push(&mv, &self.lim, &mut self.pieces);
        if result.is_ok() {
            let lim = self.lim;
            for p in &mut self.pieces {
                if !p.sampled {
                    p.sample(&lim);
                }
            }
        }
        self.result = Some(result);
    }

    /// Whether [`Planner::prepare`] copied for a move that is not built yet.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn build_due(&self) -> bool {
        self.mv.is_some() && self.result.is_none()
    }
}

impl<K: Kinematics> Planner<K> {
    /// Where `prepared` stands for the move the caller numbered `key` (see [`Preparation`]).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn preparation(&self, prepared: &PreparedMove, key: u64) -> Preparation {
        if prepared.generation != self.geometry_generation
            || prepared.key != key
            || prepared.mv.is_none()
        {
            Preparation::Stale
        } else if prepared.result.is_some() {
            Preparation::Built
        } else {
            Preparation::Copied
        }
    }

    /// Copies the planner's geometry state into `prepared` for `mv`, which the caller
    /// numbers `key` (any number that tells its moves apart); then [`PreparedMove::build`]
    /// (apart from the planner) and [`Planner::push_prepared`].
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn prepare(&self, mv: &Move, key: u64, prepared: &mut PreparedMove) {
        prepared.builder.clone_from(&self.builder);
        prepared.lim = self.lim;
        prepared.generation = self.geometry_generation;
        prepared.key = key;
        prepared.mv = Some(*mv);
        prepared.result = None;
        prepared.pieces.clear();
    }

    /// Appends the move `prepared` was built for, as [`Planner::push`] of it would: the
    /// same errors, the same window. `prepared` is then spent. Not built, or built before
    /// the planner's geometry changed: [`MotionError::Busy`], the planner unchanged;
    /// [`MotionError::QueueFull`]: `prepared` stays valid, try again after some periods.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn push_prepared(&mut self, prepared: &mut PreparedMove) -> Result<(), MotionError> {
        if matches!(self.hold, Some(h) if h.kind != StopKind::Hold) {
            return Err(MotionError::Busy("stopping"));
        }
        if self.preparation(prepared, prepared.key) != Preparation::Built {
            return Err(MotionError::Busy("prepared move out of date"));
        }
        if self.free() == 0 {
            return Err(MotionError::QueueFull);
        }
        prepared.mv = None;
        if let Some(Err(e)) = prepared.result.take() {
            return Err(e);
        }
        std::mem::swap(&mut self.builder, &mut prepared.builder);
        self.geometry_generation = self.geometry_generation.wrapping_add(1);
        let first_new = self.q.len;
        std::mem::swap(&mut self.scratch, &mut prepared.pieces);
        self.append_scratch(false);
        std::mem::swap(&mut self.scratch, &mut prepared.pieces);
        if self.q.len > first_new {
            self.update_curve(first_new);
        }
        Ok(())
    }
}
