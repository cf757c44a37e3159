//! The rig's joints by name: a [`JointId`] instead of an index into five-element arrays, so
//! the code says which joint it means (and the compiler checks every joint is handled).

use std::ops::{Index, IndexMut};

use tribo_plugin_api::{InnerBody, JointKind};

use crate::model::JOINT_NAMES;

/// One of the rig's five law-bearing joints, in the model's order (`JOINT_NAMES`): the two
/// main bearings, the big end, the small end and the piston slide.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum JointId {
    /// First main bearing (crank-block), carrying `load_share` of the main reaction.
    MainA,
    /// Second main bearing.
    MainB,
    /// Crank pin - connecting rod.
    BigEnd,
    /// Connecting rod - piston pin.
    SmallEnd,
    /// Piston - cylinder (the slide): a prismatic joint, its normal load the side thrust.
    Piston,
}

impl JointId {
    /// Every joint, in the order of the model, of law binding and of the time series columns.
    pub const ALL: [JointId; 5] = [
        JointId::MainA,
        JointId::MainB,
        JointId::BigEnd,
        JointId::SmallEnd,
        JointId::Piston,
    ];

    /// Position in [`JointId::ALL`] (and in the model's `JOINT_NAMES`).
    pub const fn index(self) -> usize {
        self as usize
    }

    /// The joint's name in rig files and results (`main_a`, ..., `piston`).
    pub const fn name(self) -> &'static str {
        JOINT_NAMES[self.index()]
    }

    /// Revolute for the bearings and pins, prismatic for the piston slide: what a law is told.
    pub const fn kind(self) -> JointKind {
        match self {
            JointId::Piston => JointKind::Prismatic,
            _ => JointKind::Revolute,
        }
    }

    /// Whether the joint is one of the two main bearings (their laws share one crank torque).
    pub const fn is_main(self) -> bool {
        matches!(self, JointId::MainA | JointId::MainB)
    }

    /// Which of the joint's bodies is the inner member: the crank's journal (A) in a main
    /// bearing, the crank pin (B, the crank) in the big end, the piston pin (A, the piston) in
    /// the small end, the piston (A) in the cylinder.
    pub const fn inner(self) -> InnerBody {
        match self {
            JointId::BigEnd => InnerBody::B,
            _ => InnerBody::A,
        }
    }
}

/// A value per joint, indexed by [`JointId`].
impl<T> Index<JointId> for [T; 5] {
    type Output = T;
    fn index(&self, id: JointId) -> &T {
        &self[id.index()]
    }
}

impl<T> IndexMut<JointId> for [T; 5] {
    fn index_mut(&mut self, id: JointId) -> &mut T {
        &mut self[id.index()]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn joint_ids_follow_the_model_order() {
        for (i, id) in JointId::ALL.into_iter().enumerate() {
            assert_eq!(id.index(), i);
            assert_eq!(id.name(), JOINT_NAMES[i]);
        }
        assert_eq!(JointId::Piston.kind(), JointKind::Prismatic);
        assert!(JointId::ALL[..4]
            .iter()
            .all(|j| j.kind() == JointKind::Revolute));
        let mut v = [0; 5];
        v[JointId::SmallEnd] = 7;
        assert_eq!(v[3], 7);
    }
}
