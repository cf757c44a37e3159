//! A rig's law-bearing joints, whatever its crank train: their names (from the rig), what each
//! is on the crank ([`Role`]), contact geometry and laws. The single-cylinder rig reads as a
//! one-cylinder engine with two mains (`main_a`, `main_b`) and its own joint names; an engine
//! has `main_1 .. main_n`, then per cylinder `big_end_k`, `small_end_k`, `piston_k`.

use super::types::Role;
use crate::model::{LawRef, RigFile};

/// One joint as the rig describes it: name, role, contact radius and length (m), laws, and
/// the dotted field of its laws in the model (`joints.NAME.laws`; on an engine a cylinder
/// joint without its own entry takes the `[joints.KIND]` table's laws, located there).
pub(super) struct JointSpec {
    pub(super) name: String,
    pub(super) role: Role,
    pub(super) contact: (f64, f64),
    pub(super) laws: Vec<LawRef>,
    pub(super) field: String,
}

impl JointSpec {
    /// The dotted field of the joint's law `i`.
    pub(super) fn law_field(&self, i: usize) -> String {
        format!("{}[{i}]", self.field)
    }
}

/// The rig's joints in order: the mains, then each cylinder's big end, small end and piston.
pub(super) fn joint_specs(f: &RigFile) -> Vec<JointSpec> {
    let Some(e) = &f.engine else {
        let roles = [
            Role::Main(0),
            Role::Main(1),
            Role::BigEnd(0),
            Role::SmallEnd(0),
            Role::Piston(0),
        ];
        return f
            .joints
            .named()
            .into_iter()
            .zip(roles)
            .map(|((name, j), role)| JointSpec {
                name: name.to_string(),
                role,
                contact: (j.radius_m, j.length_m),
                laws: j.laws.clone(),
                field: format!("joints.{name}.laws"),
            })
            .collect();
    };
    let mut out = Vec::new();
    for (i, m) in e.mains.iter().enumerate() {
        let name = format!("main_{}", i + 1);
        out.push(JointSpec {
            laws: e.laws.get(&name).cloned().unwrap_or_default(),
            field: format!("joints.{name}.laws"),
            name,
            role: Role::Main(i),
            contact: (m.radius_m, m.length_m),
        });
    }
    for k in 0..e.cylinders.len() {
        for (kind, role, template) in [
            ("big_end", Role::BigEnd(k), &f.joints.big_end),
            ("small_end", Role::SmallEnd(k), &f.joints.small_end),
            ("piston", Role::Piston(k), &f.joints.piston),
        ] {
            let name = format!("{kind}_{}", k + 1);
            // A law set's entry for this joint (located through its origin), else the
            // `[joints.KIND]` table's laws, shared by every cylinder.
            let (laws, field) = match e.laws.get(&name) {
                Some(laws) => (laws.clone(), format!("joints.{name}.laws")),
                None => (template.laws.clone(), format!("joints.{kind}.laws")),
            };
            out.push(JointSpec {
                name,
                role,
                contact: (template.radius_m, template.length_m),
                laws,
                field,
            });
        }
    }
    out
}
