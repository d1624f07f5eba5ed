//! Which foot, and where both soles stand in a double-support stance: what the footholds
//! produce and the gait, the IK and the checks consume.

use nalgebra::Isometry3;

/// Which foot.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Foot {
    /// The right foot (it leads each step, §6.1).
    Right,
    /// The left foot.
    Left,
}

impl Foot {
    /// Both feet, in `[right, left]` order.
    pub const BOTH: [Foot; 2] = [Foot::Right, Foot::Left];

    /// 0 for the right foot, 1 for the left: the index into every `[right, left]` pair.
    pub fn index(self) -> usize {
        match self {
            Foot::Right => 0,
            Foot::Left => 1,
        }
    }
}

/// Both feet's sole poses in one double-support stance.
#[derive(Debug, Clone, PartialEq)]
pub struct Stance {
    /// Right sole centre (z = sole normal).
    pub right: Isometry3<f64>,
    /// Left sole centre.
    pub left: Isometry3<f64>,
    /// Index of the step stood on (in ascending order), `None` on the floor.
    pub step: Option<usize>,
}

impl Stance {
    /// The pose of one foot.
    pub fn foot(&self, f: Foot) -> &Isometry3<f64> {
        match f {
            Foot::Right => &self.right,
            Foot::Left => &self.left,
        }
    }
}
