//! Axis names and the 9-component axis-space vector (X Y Z A B C U V W), mm or degrees.

/// Number of axes of the canonical machine (X Y Z A B C U V W).
pub const AXES: usize = 9;

/// A position, velocity or direction in axis space, indexed by [`Axis`] as `usize`.
pub type AxisVec = [f64; AXES];

/// The canonical axes, in the order of [`AxisVec`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[allow(missing_docs)]
pub enum Axis {
    X,
    Y,
    Z,
    A,
    B,
    C,
    U,
    V,
    W,
}

impl Axis {
    /// All axes in vector order.
    pub const ALL: [Axis; AXES] = [
        Axis::X,
        Axis::Y,
        Axis::Z,
        Axis::A,
        Axis::B,
        Axis::C,
        Axis::U,
        Axis::V,
        Axis::W,
    ];

    /// Axis letter.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn letter(self) -> char {
        ['X', 'Y', 'Z', 'A', 'B', 'C', 'U', 'V', 'W'][self as usize]
    }

    /// Axis from its letter (upper or lower case).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn from_letter(c: char) -> Option<Axis> {
        Axis::ALL
            .iter()
            .copied()
            .find(|a| a.letter() == c.to_ascii_uppercase())
    }
}

pub(crate) fn sub(a: &AxisVec, b: &AxisVec) -> AxisVec {
    let mut r = [0.0; AXES];
    for i in 0..AXES {
        r[i] = a[i] - b[i];
    }
    r
}

pub(crate) fn add_scaled(a: &AxisVec, b: &AxisVec, k: f64) -> AxisVec {
    let mut r = [0.0; AXES];
    for i in 0..AXES {
        r[i] = a[i] + b[i] * k;
    }
    r
}

pub(crate) fn scale(a: &AxisVec, k: f64) -> AxisVec {
    let mut r = [0.0; AXES];
    for i in 0..AXES {
        r[i] = a[i] * k;
    }
    r
}

pub(crate) fn dot(a: &AxisVec, b: &AxisVec) -> f64 {
    let mut s = 0.0;
    for i in 0..AXES {
        s += a[i] * b[i];
    }
    s
}

pub(crate) fn norm(a: &AxisVec) -> f64 {
    dot(a, a).sqrt()
}

/// Length of the X Y Z part.
pub(crate) fn norm_xyz(a: &AxisVec) -> f64 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}

pub(crate) fn is_finite(a: &AxisVec) -> bool {
    a.iter().all(|x| x.is_finite())
}
