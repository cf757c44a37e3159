//! The crank models the solver runs on, behind one type: the single-cylinder rig's
//! [`Mechanism`] (absolute coordinates, 9 x 9, the thesis rig's own solve) and an engine's
//! [`CrankTrain`] (closed form per cylinder). Each owns its scratch (the configuration's
//! kinematics and the last solve's reactions), so one evaluation asks the model for kinematics
//! once, then for reactions under any number of friction loads, and reads per joint what the
//! laws need: relative velocity, normal load, reaction components.

use nalgebra::Vector2;

use super::types::{Bodies, Control, Role};
use crate::engine::{CrankTrain, CylinderLoads, TrainKinematics, TrainLoads, TrainReactions};
use crate::gas::{cycle_angle, GasModel, GasState, LawGas};
use crate::mechanics::{JointLoads, Kinematics, Mechanism, Reactions};
use tribo_plugin_api::contract::STANDARD_ATMOSPHERE_PA;

/// One solve's normal loads at a glance: what the friction/reaction iteration judges them by.
#[derive(Debug, Clone, Copy)]
pub(crate) struct LoadScan {
    /// The largest load, N (a non-finite one aside).
    pub(crate) largest_n: f64,
    /// The largest change of a load from the solve before, N.
    pub(crate) change_n: f64,
    /// Whether every load is finite.
    pub(crate) finite: bool,
}

/// A crank model with its scratch.
#[derive(Clone)]
pub(crate) enum Crank {
    /// The single-cylinder rig's mechanism, its main reaction split by the rig's load shares.
    Rig(Box<RigCrank>),
    /// A multi-cylinder engine's crank train.
    Train(Box<TrainCrank>),
}

/// The single-cylinder rig: [`Mechanism`], the two mains' shares of its main reaction.
#[derive(Clone)]
pub(crate) struct RigCrank {
    mech: Mechanism,
    shares: [f64; 2],
    kin: Kinematics,
    re: Reactions,
}

/// An engine: [`CrankTrain`], each cylinder's piston position at its TDC and 4-stroke phase.
#[derive(Clone)]
pub(crate) struct TrainCrank {
    train: CrankTrain,
    /// Each cylinder's piston position at its top dead centre from the crank centre along its
    /// axis, m: `sqrt((l + r)^2 - e^2)` for the offset `e`.
    tdc_position: Vec<f64>,
    /// Each cylinder's 4-stroke phase from the firing order, rad.
    phases: Vec<f64>,
    kin: TrainKinematics,
    re: TrainReactions,
    loads: TrainLoads,
    /// The elastic crankshaft's throws (`None`: a rigid crank).
    elastic: Option<Box<Elastic>>,
}

/// Each throw's twist from the crank's reference (angle, speed) and the net torque of the
/// shaft's sections on it (N m): what the chain hands an evaluation.
pub(crate) type ThrowLoads<'a> = (&'a [(f64, f64)], &'a [f64]);

/// An elastic crankshaft's throws as one evaluation sees them: what the chain's integration
/// sets (each throw's twist from the crank's reference angle and speed, the net torque of the
/// shaft's sections on it) and what the solve returns (each throw's acceleration).
#[derive(Clone, Debug)]
pub(crate) struct Elastic {
    /// Whether the twist and torques below hold for the evaluation under way (a rigid
    /// evaluation of the same run clears it).
    active: bool,
    /// Each throw's angle and speed minus the reference's, rad, rad/s.
    twist: Vec<(f64, f64)>,
    /// Net torque of the sections on each throw, N m.
    torque: Vec<f64>,
    /// Each throw's own inertia about the axis, kg m^2.
    inertia: Vec<f64>,
    /// Per main: the throws its friction torque acts on and their shares (summing to 1).
    mains: Vec<Vec<(usize, f64)>>,
    /// Each throw's share of the mains' friction torque in the last solve, N m.
    main_torque: Vec<f64>,
    /// Each throw's acceleration from the last solve, rad/s^2.
    alpha: Vec<f64>,
    /// Scratch: the throws' torques at zero and unit acceleration.
    probe: [Vec<f64>; 2],
}

impl Crank {
    /// The single-cylinder rig's model: `mech` with the mains' load `shares`.
    pub(crate) fn rig(mech: Mechanism, shares: [f64; 2]) -> Self {
        let kin = mech.kinematics(0.0, 0.0);
        let re = kin.reactions(0.0, &JointLoads::default());
        Crank::Rig(Box::new(RigCrank {
            mech,
            shares,
            kin,
            re,
        }))
    }

    /// An engine's model: `train` with its cylinders' 4-stroke `phases`.
    pub(crate) fn train(train: CrankTrain, phases: Vec<f64>) -> Self {
        let geo = train.geometry();
        let tdc_position = geo
            .cylinders
            .iter()
            .map(|c| {
                let reach = c.rod.length_m + geo.crank_radius_m;
                let e = c.pin_offset_m + c.crank_offset_m;
                (reach * reach - e * e).sqrt()
            })
            .collect();
        let n = geo.cylinders.len();
        Crank::Train(Box::new(TrainCrank {
            tdc_position,
            phases,
            kin: TrainKinematics::default(),
            re: TrainReactions::default(),
            loads: TrainLoads {
                main_torque_nm: 0.0,
                cylinders: vec![CylinderLoads::default(); n],
            },
            train,
            elastic: None,
        }))
    }

    /// Make an engine's crankshaft elastic: its throws turn each with its own inertia
    /// ([`CrankTrain::throw_inertias`]), each main's friction on the throws either side of it
    /// in the lever shares of their loads. Nothing on the single-cylinder rig.
    pub(crate) fn make_elastic(&mut self) {
        let Crank::Train(t) = self else { return };
        let n = t.train.geometry().throws.len();
        let mut mains = vec![Vec::new(); t.train.geometry().mains_axial_m.len()];
        for (j, split) in t.train.main_split().iter().enumerate() {
            for (main, w) in split {
                if *w > 0.0 {
                    mains[*main].push((j, *w));
                }
            }
        }
        for m in &mut mains {
            let total: f64 = m.iter().map(|(_, w)| w).sum();
            m.iter_mut().for_each(|(_, w)| *w /= total);
        }
        t.elastic = Some(Box::new(Elastic {
            active: false,
            twist: vec![(0.0, 0.0); n],
            torque: vec![0.0; n],
            inertia: t.train.throw_inertias(),
            mains,
            main_torque: vec![0.0; n],
            alpha: vec![0.0; n],
            probe: [vec![0.0; n], vec![0.0; n]],
        }));
    }

    /// Each throw's inertia about the axis with its rods and pistons, averaged over a
    /// revolution (the reciprocating masses at their cycle mean), kg m^2: an elastic
    /// crankshaft's throw nodes in the linearised chain (empty on the single-cylinder rig).
    pub(crate) fn throw_mean_inertias(&self) -> Vec<f64> {
        let Crank::Train(t) = self else {
            return Vec::new();
        };
        let own = t.train.throw_inertias();
        let n = own.len();
        let samples = 360;
        (0..n)
            .map(|j| {
                let mut twist = vec![(0.0, 0.0); n];
                twist[j].1 = 1.0;
                (0..samples)
                    .map(|k| {
                        let theta = std::f64::consts::TAU * k as f64 / samples as f64;
                        let e = |tw: &[(f64, f64)]| {
                            t.train
                                .twisted_mechanical_energy(theta, 0.0, tw, Some(&own))
                        };
                        2.0 * (e(&twist) - e(&[]))
                    })
                    .sum::<f64>()
                    / samples as f64
            })
            .collect()
    }

    /// Each throw's own inertia on an elastic crankshaft (empty on a rigid one), kg m^2.
    pub(crate) fn throw_inertias(&self) -> &[f64] {
        match self {
            Crank::Train(t) => t.elastic.as_ref().map_or(&[], |e| &e.inertia),
            Crank::Rig(_) => &[],
        }
    }

    /// The next evaluations see throw `j` turned by `twist[j]` (angle, speed) from the crank's
    /// reference and loaded by the sections' net torque `torque[j]` (N m), to be solved with
    /// [`Control::Throws`]; `None` makes them rigid again.
    pub(crate) fn set_throws(&mut self, throws: Option<ThrowLoads<'_>>) {
        let Crank::Train(t) = self else { return };
        let Some(e) = t.elastic.as_mut() else { return };
        match throws {
            Some((twist, torque)) => {
                e.active = true;
                e.twist.copy_from_slice(twist);
                e.torque.copy_from_slice(torque);
            }
            None => e.active = false,
        }
    }

    /// Each throw's acceleration from the last solve with [`Control::Throws`], rad/s^2.
    pub(crate) fn throw_alphas(&self) -> &[f64] {
        match self {
            Crank::Train(t) => t.elastic.as_ref().map_or(&[], |e| &e.alpha),
            Crank::Rig(_) => &[],
        }
    }

    /// The twisted crank train's kinetic and potential energy, J: throw `j` turned by
    /// `twist[j]` from `theta`, `omega` (the rigid crank's energy without an elastic shaft).
    pub(crate) fn twisted_energy(&self, theta: f64, omega: f64, twist: &[(f64, f64)]) -> f64 {
        match self {
            Crank::Train(t) if t.elastic.is_some() => t.train.twisted_mechanical_energy(
                theta,
                omega,
                twist,
                t.elastic.as_ref().map(|e| e.inertia.as_slice()),
            ),
            _ => self.mechanical_energy(theta, omega),
        }
    }

    /// Number of cylinders.
    pub(crate) fn cylinders(&self) -> usize {
        match self {
            Crank::Rig(_) => 1,
            Crank::Train(t) => t.train.geometry().cylinders.len(),
        }
    }

    /// The mechanism of the single-cylinder rig (`None` on an engine).
    pub(crate) fn mechanism(&self) -> Option<&Mechanism> {
        match self {
            Crank::Rig(r) => Some(&r.mech),
            Crank::Train(_) => None,
        }
    }

    /// The crank train of an engine (`None` on the single-cylinder rig).
    pub(crate) fn crank_train(&self) -> Option<&CrankTrain> {
        match self {
            Crank::Rig(_) => None,
            Crank::Train(t) => Some(&t.train),
        }
    }

    /// The configuration at crank angle `theta` (accumulated) and speed `omega`, with each
    /// cylinder's gas force from `gas` (one model per cylinder, none without gas loads; a
    /// vented crankcase read at the crank speed `gas_omega`; every cylinder's pressure
    /// `cylinder_pa` instead of its model's where given). Each cylinder's gas state as its
    /// laws are handed it goes to `law_gas`. Returns the power into the gas (minus the gas
    /// forces' power on the pistons), W.
    #[inline]
    pub(crate) fn kinematics(
        &mut self,
        theta: f64,
        omega: f64,
        gas: &[GasModel],
        (gas_omega, cylinder_pa): (f64, Option<f64>),
        law_gas: &mut Vec<LawGas>,
    ) -> f64 {
        law_gas.clear();
        let state = |g: &GasModel, s: GasState| match cylinder_pa {
            Some(p) => g.with_cylinder_pressure(s, p),
            None => s,
        };
        match self {
            Crank::Rig(r) => r.kinematics(theta, omega, gas.first(), gas_omega, state, law_gas),
            Crank::Train(t) => t.kinematics(theta, omega, gas, gas_omega, state, law_gas),
        }
    }

    /// The two bodies of the joint `role` in the current configuration, body A first: a main
    /// bearing, crank and block (at rest); a big end, rod and crank; a small end, piston and
    /// rod (angles in the plane, rad, and angular velocities, rad/s; an engine's piston is
    /// turned by its bank angle and does not rotate); a slide, the piston's position and speed
    /// along the cylinder axis (m, m/s) and the cylinder. Their relative velocity
    /// ([`Bodies::relative`]) is the crank speed, rod minus crank, piston minus rod, the piston
    /// speed.
    #[inline]
    pub(crate) fn bodies(&self, role: Role) -> Bodies {
        let block = (0.0, 0.0);
        match self {
            Crank::Rig(r) => {
                let (q, qd) = (&r.kin.q, &r.kin.qd);
                let crank = (q[2], qd[2]);
                let rod = (q[5], qd[5]);
                match role {
                    Role::Main(_) => Bodies { a: crank, b: block },
                    Role::BigEnd(_) => Bodies { a: rod, b: crank },
                    Role::SmallEnd(_) => Bodies {
                        a: (q[8], qd[8]),
                        b: rod,
                    },
                    Role::Piston(_) => Bodies {
                        a: (q[7], qd[7]),
                        b: block,
                    },
                }
            }
            Crank::Train(t) => {
                let kin = &t.kin;
                let crank = (kin.theta, kin.omega);
                let geo = t.train.geometry();
                let bank = |k: usize| geo.cylinders[k].bank_rad;
                let rod = |k: usize| {
                    let c = &kin.cylinders[k];
                    (bank(k) + c.rod_angle_rad, c.rod_rate_rad_s)
                };
                // On an elastic shaft a pin turns with its throw, a journal as the throws
                // either side of its main in their shares.
                let pin = |k: usize| {
                    kin.throws
                        .get(geo.cylinders[k].throw)
                        .copied()
                        .unwrap_or(crank)
                };
                let journal = |i: usize| match &t.elastic {
                    Some(e) if e.active => e.mains[i].iter().fold((0.0, 0.0), |(a, w), (j, s)| {
                        (a + s * kin.throws[*j].0, w + s * kin.throws[*j].1)
                    }),
                    _ => crank,
                };
                match role {
                    Role::Main(i) => Bodies {
                        a: journal(i),
                        b: block,
                    },
                    Role::BigEnd(k) => Bodies {
                        a: rod(k),
                        b: pin(k),
                    },
                    Role::SmallEnd(k) => Bodies {
                        a: (bank(k), 0.0),
                        b: rod(k),
                    },
                    Role::Piston(k) => Bodies {
                        a: (
                            kin.cylinders[k].piston_position_m,
                            kin.cylinders[k].piston_speed_m_s,
                        ),
                        b: block,
                    },
                }
            }
        }
    }

    /// Solve the reactions in the current configuration under the friction of each joint's
    /// laws, `totals[j]` for the joint `roles[j]` (the mains' torques add up); returns the
    /// crank acceleration (the control's, or the one the drive torque causes).
    #[inline]
    pub(crate) fn solve(&mut self, control: Control, roles: &[Role], totals: &[f64]) -> f64 {
        match self {
            Crank::Rig(r) => {
                let mut loads = JointLoads::default();
                for (role, total) in roles.iter().zip(totals) {
                    match role {
                        Role::Main(_) => loads.main_torque_nm += total,
                        Role::BigEnd(_) => loads.big_end_torque_nm = *total,
                        Role::SmallEnd(_) => loads.small_end_torque_nm = *total,
                        Role::Piston(_) => loads.slide_force_n = *total,
                    }
                }
                let alpha = match control {
                    Control::Acceleration(alpha) => alpha,
                    Control::Torque(torque) => r.kin.alpha_for_torque(torque, &loads),
                    // The rig's crank is rigid: never driven by throws.
                    Control::Throws => 0.0,
                };
                r.re = r.kin.reactions(alpha, &loads);
                alpha
            }
            Crank::Train(t) => {
                let loads = &mut t.loads;
                loads.main_torque_nm = 0.0;
                loads
                    .cylinders
                    .iter_mut()
                    .for_each(|c| *c = CylinderLoads::default());
                for (role, total) in roles.iter().zip(totals) {
                    match *role {
                        Role::Main(_) => loads.main_torque_nm += total,
                        Role::BigEnd(c) => loads.cylinders[c].big_end_torque_nm = *total,
                        Role::SmallEnd(c) => loads.cylinders[c].small_end_torque_nm = *total,
                        Role::Piston(c) => loads.cylinders[c].slide_force_n = *total,
                    }
                }
                if let (Control::Throws, Some(e)) = (control, t.elastic.as_deref_mut()) {
                    return solve_throws(&t.train, &t.kin, roles, totals, loads, e, &mut t.re);
                }
                let alpha = match control {
                    Control::Acceleration(alpha) => alpha,
                    Control::Torque(torque) => t.train.alpha_for_torque(&t.kin, torque, loads),
                    // A rigid crank has no throws of its own: not driven by them.
                    Control::Throws => 0.0,
                };
                t.train.reactions_into(&t.kin, alpha, loads, &mut t.re);
                alpha
            }
        }
    }

    /// Each joint's normal load from the last solve, `out[j]` for `roles[j]` (N), scanned in
    /// the same pass ([`LoadScan`]; its change measured against `prev`, the loads of the solve
    /// before, for a caller that has them): the iteration's scales are taken from the values as
    /// they are made, not read back from `out` (wide reads of narrow stores just made stall the
    /// processor's store forwarding).
    #[inline]
    pub(crate) fn normals_against(
        &self,
        roles: &[Role],
        out: &mut [f64],
        prev: &[f64],
    ) -> LoadScan {
        let mut scan = LoadScan {
            largest_n: 0.0,
            change_n: 0.0,
            finite: true,
        };
        let mut put = |o: &mut f64, p: f64, n: f64| {
            *o = n;
            scan.largest_n = scan.largest_n.max(n);
            scan.change_n = scan.change_n.max((p - n).abs());
            scan.finite &= n.is_finite();
        };
        match self {
            Crank::Rig(r) => {
                let main = r.re.main_n.norm();
                for ((o, role), p) in out.iter_mut().zip(roles).zip(prev) {
                    let n = match *role {
                        Role::Main(i) => main * r.shares[i],
                        Role::BigEnd(_) => r.re.big_end_n.norm(),
                        Role::SmallEnd(_) => r.re.small_end_n.norm(),
                        Role::Piston(_) => r.re.slide_lateral_n.abs(),
                    };
                    put(o, *p, n);
                }
            }
            Crank::Train(t) => {
                for ((o, role), p) in out.iter_mut().zip(roles).zip(prev) {
                    put(o, *p, t.reaction(*role).0.norm());
                }
            }
        }
        scan
    }

    /// The reaction the laws of joint `role` see in the last solve: its force (components:
    /// global frame for bearings and pins; for a slide, along its axis and across it) and
    /// moment.
    #[inline]
    pub(crate) fn reaction(&self, role: Role) -> (Vector2<f64>, f64) {
        match self {
            Crank::Rig(r) => match role {
                Role::Main(i) => (r.re.main_n * r.shares[i], 0.0),
                Role::BigEnd(_) => (r.re.big_end_n, 0.0),
                Role::SmallEnd(_) => (r.re.small_end_n, 0.0),
                Role::Piston(_) => (
                    Vector2::new(0.0, r.re.slide_lateral_n),
                    r.re.slide_moment_nm,
                ),
            },
            Crank::Train(t) => t.reaction(role),
        }
    }

    /// The drive torque of the last solve, N m.
    #[inline]
    pub(crate) fn drive_torque(&self) -> f64 {
        match self {
            Crank::Rig(r) => r.re.drive_torque_nm,
            Crank::Train(t) => t.re.drive_torque_nm,
        }
    }

    /// Cylinder `k`'s side thrust (the lateral reaction of its slide, signed) in the last
    /// solve, N.
    #[inline]
    pub(crate) fn lateral(&self, k: usize) -> f64 {
        match self {
            Crank::Rig(r) => r.re.slide_lateral_n,
            Crank::Train(t) => t.re.cylinders[k].slide_lateral_n,
        }
    }

    /// Kinetic plus potential energy of the moving parts at crank angle `theta` and speed
    /// `omega`, J: what the motor's work changes over a transient run.
    /// The crank train's inertia about the crank axis averaged over a revolution, kg m^2
    /// (the reciprocating masses at their cycle mean): `2 (E(theta, w) - E(theta, 0)) / w^2`
    /// over 360 angles.
    pub(crate) fn mean_inertia_kg_m2(&self) -> f64 {
        let n = 360;
        let w = 1.0;
        (0..n)
            .map(|k| {
                let theta = std::f64::consts::TAU * k as f64 / n as f64;
                2.0 * (self.mechanical_energy(theta, w) - self.mechanical_energy(theta, 0.0))
            })
            .sum::<f64>()
            / n as f64
    }

    pub(crate) fn mechanical_energy(&self, theta: f64, omega: f64) -> f64 {
        match self {
            Crank::Rig(r) => {
                // Positions and velocities only: the gas force does not change them.
                let (st, _) = r.mech.solve(theta, omega, 0.0, &JointLoads::default());
                r.mech.kinetic_energy(&st.qd) + r.mech.potential_energy(&st.q)
            }
            Crank::Train(t) => t.train.mechanical_energy(theta, omega),
        }
    }

    /// The last solve's loads for a crank-angle sample: cylinder 1's big-end force and the
    /// mains' total (x, y), N; each cylinder's big-end force and side thrust, and each main's
    /// force (empty on the single-cylinder rig, whose one cylinder is the first two).
    pub(crate) fn loads_sample(&self) -> LoadsSample {
        match self {
            Crank::Rig(r) => LoadsSample {
                big_end_n: [r.re.big_end_n.x, r.re.big_end_n.y],
                main_n: [r.re.main_n.x, r.re.main_n.y],
                cylinders: Vec::new(),
                mains_n: Vec::new(),
            },
            Crank::Train(t) => {
                let first = t.re.cylinders.first().map(|c| c.big_end_n);
                LoadsSample {
                    big_end_n: first.map_or([0.0; 2], |b| [b.x, b.y]),
                    main_n: [t.re.main_total_n.x, t.re.main_total_n.y],
                    cylinders: t
                        .re
                        .cylinders
                        .iter()
                        .map(|c| ([c.big_end_n.x, c.big_end_n.y], c.slide_lateral_n))
                        .collect(),
                    mains_n: t.re.mains_n.iter().map(|m| [m.x, m.y]).collect(),
                }
            }
        }
    }
}

/// The loads of one solve, as a crank-angle sample reports them (see [`Crank::loads_sample`]).
pub(crate) struct LoadsSample {
    pub(crate) big_end_n: [f64; 2],
    pub(crate) main_n: [f64; 2],
    /// Per cylinder: big-end force (x, y) and side thrust, N.
    pub(crate) cylinders: Vec<([f64; 2], f64)>,
    pub(crate) mains_n: Vec<[f64; 2]>,
}

impl RigCrank {
    /// The mechanism's configuration with the gas force of `gas` (if any), and the gas state
    /// its laws see: the gas model's, or the atmosphere, the piston travel read from the
    /// positions and the angle within one 4-stroke cycle.
    #[inline]
    fn kinematics(
        &mut self,
        theta: f64,
        omega: f64,
        gas: Option<&GasModel>,
        gas_omega: f64,
        state: impl Fn(&GasModel, GasState) -> GasState,
        law_gas: &mut Vec<LawGas>,
    ) -> f64 {
        match gas {
            None => {
                self.mech.kinematics_into(theta, omega, 0.0, &mut self.kin);
                law_gas.push(LawGas {
                    cylinder_pa: STANDARD_ATMOSPHERE_PA,
                    crankcase_pa: STANDARD_ATMOSPHERE_PA,
                    piston_from_tdc_m: self.mech.piston_travel(&self.kin.q),
                    cycle_angle_rad: cycle_angle(theta),
                });
                0.0
            }
            Some(g) => {
                let s = state(g, g.at(theta, gas_omega));
                self.mech
                    .kinematics_into(theta, omega, s.force_n, &mut self.kin);
                law_gas.push((&s).into());
                -s.force_n * self.kin.qd[7]
            }
        }
    }
}

impl TrainCrank {
    /// The train's configuration with each cylinder's gas force (its model at its own local
    /// angle and piston travel), and the gas state each cylinder's laws see.
    #[inline]
    fn kinematics(
        &mut self,
        theta: f64,
        omega: f64,
        gas: &[GasModel],
        gas_omega: f64,
        state: impl Fn(&GasModel, GasState) -> GasState,
        law_gas: &mut Vec<LawGas>,
    ) -> f64 {
        let twist = match &self.elastic {
            Some(e) if e.active => e.twist.as_slice(),
            _ => &[],
        };
        self.train
            .twisted_kinematics_into(theta, omega, twist, &[], &mut self.kin);
        // One crankcase under every piston: its pressure from the summed travel (a sealed
        // one's volume) and the engine's crank angle (a vented one's table).
        let crankcase_pa = gas.first().map_or(STANDARD_ATMOSPHERE_PA, |g| {
            let travel: f64 = (self.kin.cylinders.iter().zip(&self.tdc_position))
                .map(|(c, top)| top - c.piston_position_m)
                .sum();
            g.crankcase_pa(theta, gas_omega, travel)
        });
        let mut power = 0.0;
        for (k, c) in self.kin.cylinders.iter_mut().enumerate() {
            let travel = self.tdc_position[k] - c.piston_position_m;
            match gas.get(k) {
                // The volume follows the piston's true travel (with offsets, its dead centres
                // are not at local angles 0 and pi); the valve events stay at those angles.
                Some(g) => {
                    let state = state(g, g.with_crankcase(c.local_angle_rad, travel, crankcase_pa));
                    c.piston_force_n = state.force_n;
                    power += state.force_n * c.piston_speed_m_s;
                    law_gas.push((&state).into());
                }
                None => law_gas.push(LawGas {
                    cylinder_pa: STANDARD_ATMOSPHERE_PA,
                    crankcase_pa: STANDARD_ATMOSPHERE_PA,
                    piston_from_tdc_m: travel,
                    cycle_angle_rad: cycle_angle(c.local_angle_rad + self.phases[k]),
                }),
            }
        }
        -power
    }

    /// The reaction a joint's laws see: its force (components, global frame) and moment.
    #[inline]
    fn reaction(&self, role: Role) -> (Vector2<f64>, f64) {
        let re = &self.re;
        match role {
            Role::Main(i) => (re.mains_n[i], 0.0),
            Role::BigEnd(k) => (re.cylinders[k].big_end_n, 0.0),
            Role::SmallEnd(k) => (re.cylinders[k].small_end_n, 0.0),
            // As on the single-cylinder rig: the side thrust as the y component.
            Role::Piston(k) => (
                Vector2::new(0.0, re.cylinders[k].slide_lateral_n),
                re.cylinders[k].slide_moment_nm,
            ),
        }
    }
}

/// The elastic crankshaft's solve: each main's friction torque shared out to its throws, each
/// throw's acceleration from its own balance (its torque is affine in its own acceleration
/// alone: probed at 0 and 1), then the reactions at those accelerations. Returns the first
/// throw's acceleration.
fn solve_throws(
    train: &CrankTrain,
    kin: &TrainKinematics,
    roles: &[Role],
    totals: &[f64],
    loads: &TrainLoads,
    e: &mut Elastic,
    re: &mut TrainReactions,
) -> f64 {
    e.main_torque.fill(0.0);
    for (role, total) in roles.iter().zip(totals) {
        if let Role::Main(i) = *role {
            for (j, share) in &e.mains[i] {
                e.main_torque[*j] += share * total;
            }
        }
    }
    let n = e.alpha.len();
    for (p, a) in [0.0, 1.0].into_iter().enumerate() {
        e.alpha.fill(a);
        train.twisted_reactions_into(kin, (&e.alpha, &e.inertia, &e.main_torque), loads, re);
        for j in 0..n {
            e.probe[p][j] = e.inertia[j] * a - e.main_torque[j]
                + re.throw_torques_nm.get(j).copied().unwrap_or(0.0);
        }
    }
    for j in 0..n {
        // d(torque)/d(alpha) is the throw's effective inertia with its rods and pistons (> 0).
        e.alpha[j] = (e.torque[j] - e.probe[0][j]) / (e.probe[1][j] - e.probe[0][j]);
    }
    train.twisted_reactions_into(kin, (&e.alpha, &e.inertia, &e.main_torque), loads, re);
    // The drive torque as the power into the throws over the reference speed (each throw
    // takes the sections' net torque at its own speed), so that drive torque times crank
    // speed is the crank train's power, its mean the laws' dissipation; at a standstill the
    // throws' torques summed.
    if kin.omega.abs() > 1.0 {
        let power: f64 = (e.torque.iter().zip(&kin.throws))
            .map(|(t, (_, w))| t * w)
            .sum();
        re.drive_torque_nm = power / kin.omega;
    }
    e.alpha.first().copied().unwrap_or(0.0)
}
