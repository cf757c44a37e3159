//! The multi-cylinder crank train: any number of cylinders on any number of throws, inline, V
//! or boxer, with pin and crank offsets, counterweights per web and main bearings between the
//! throws (`docs/engines.md`).
//!
//! With the crank's motion known, each cylinder's rod and piston are an independent subsystem
//! (6 coordinates, 6 constraints) solved in closed form in the cylinder's own frame; the crank
//! then gives the drive torque and the main reactions. Everything is affine in the crank
//! acceleration and in each friction load, so a torque-driven crank needs the drive torque at
//! two accelerations only, and the cost grows linearly with the cylinder count.
//!
//! Frame: global y vertical (up), x across, angles counter-clockwise seen from the drive end.
//! Cylinder `k` is the single-cylinder rig of `mechanics` rotated by its bank angle `beta_k`:
//! local +y along its axis towards the head, local crank angle `theta_k = theta + phi_j - beta_k`
//! (0 at its top dead centre) for throw angle `phi_j`.

use std::f64::consts::TAU;

use nalgebra::Vector2;

/// Why a crank train cannot be built (the configuration layer checks the same with file
/// locations; these are the core's own guards).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EngineError {
    /// Fewer than two mains, or mains not in strictly increasing axial order.
    #[error("the main bearings must be at least two, in strictly increasing axial order")]
    Mains,
    /// A throw outside the span of the mains, or two throws at one axial position.
    #[error("throw {throw} at {axial_m} m must lie strictly between the first and last main, apart from every other throw")]
    ThrowPlace {
        /// Throw (1-based).
        throw: usize,
        /// Its axial position, m.
        axial_m: f64,
    },
    /// A cylinder on a throw that does not exist.
    #[error("cylinder {cylinder} runs on throw {throw}, but the crank has {throws} throws")]
    NoThrow {
        /// Cylinder (1-based).
        cylinder: usize,
        /// The throw it names (1-based).
        throw: usize,
        /// Throws of the crank.
        throws: usize,
    },
    /// A rod too short for the crank radius and offset: the mechanism would lock.
    #[error("cylinder {cylinder}: the rod ({length_m} m) must be longer than the crank radius plus the offset ({reach_m} m)")]
    RodTooShort {
        /// Cylinder (1-based).
        cylinder: usize,
        /// Rod length, m.
        length_m: f64,
        /// Crank radius plus |pin offset + crank offset|, m.
        reach_m: f64,
    },
    /// The firing order is not a permutation of the cylinder numbers.
    #[error("the firing order {order:?} is not a permutation of 1..{cylinders}")]
    NotPermutation {
        /// The order as given.
        order: Vec<usize>,
        /// Number of cylinders.
        cylinders: usize,
    },
    /// The firing order does not fit the crank: no choice of each cylinder's firing TDC makes
    /// the cylinders fire in this order, one at a time, within one 720-degree cycle.
    #[error("the firing order {order:?} does not fit the crank: with top dead centres at {tdc_deg:?} degrees of crank angle the cylinders cannot fire in this order, one at a time, within one 720-degree cycle")]
    OrderMisfit {
        /// The order as given.
        order: Vec<usize>,
        /// Each cylinder's top dead centre, degrees of crank angle in [0, 360).
        tdc_deg: Vec<f64>,
    },
}

/// A counterweight on one web: a point mass on the crank.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Counterweight {
    /// Mass, kg.
    pub mass_kg: f64,
    /// Radius of its centre of mass from the crank axis, m.
    pub radius_m: f64,
    /// Angle from its throw's pin, in the direction of rotation, rad (pi: opposite the pin).
    pub angle_rad: f64,
}

/// One crank throw (a crank pin with its two webs).
#[derive(Debug, Clone, PartialEq)]
pub struct ThrowGeometry {
    /// Pin angle added to the engine's crank angle, rad.
    pub angle_rad: f64,
    /// Axial position along the crank, m.
    pub axial_m: f64,
    /// Counterweights of its webs (at most two in a rig file).
    pub counterweights: Vec<Counterweight>,
}

/// A connecting rod.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RodGeometry {
    /// Mass, kg.
    pub mass_kg: f64,
    /// In-plane moment of inertia about its centre of mass, kg m^2.
    pub inertia_kg_m2: f64,
    /// Length between pin centres, m.
    pub length_m: f64,
    /// Centre of mass from the big-end centre, m.
    pub com_from_big_end_m: f64,
}

/// One cylinder with its rod and piston.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CylinderGeometry {
    /// The throw its rod runs on (0-based index into the throws).
    pub throw: usize,
    /// Bank angle: the cylinder axis from the vertical, in the direction of rotation, rad.
    pub bank_rad: f64,
    /// Piston-pin offset from the bore axis, across it (cylinder frame +x), m.
    pub pin_offset_m: f64,
    /// Bore axis offset from the crank centre, across it (cylinder frame +x), m.
    pub crank_offset_m: f64,
    /// Its connecting rod.
    pub rod: RodGeometry,
    /// Piston assembly mass (centre of mass at the pin), kg.
    pub piston_mass_kg: f64,
}

/// The whole crank train, SI units.
#[derive(Debug, Clone, PartialEq)]
pub struct EngineGeometry {
    /// Crank radius (half the stroke) of every throw, m.
    pub crank_radius_m: f64,
    /// The crank's balanced part: mass on the axis, kg.
    pub crank_mass_kg: f64,
    /// The crank's moment of inertia about its axis without the counterweights, kg m^2.
    pub crank_inertia_kg_m2: f64,
    /// Inertia a drive adds to the crank, kg m^2.
    pub drive_inertia_kg_m2: f64,
    /// Gravitational acceleration along global -y, m/s^2 (0: gravity off).
    pub gravity_m_s2: f64,
    /// Axial positions of the main bearings, m, strictly increasing.
    pub mains_axial_m: Vec<f64>,
    /// The throws.
    pub throws: Vec<ThrowGeometry>,
    /// The cylinders, in cylinder-number order.
    pub cylinders: Vec<CylinderGeometry>,
}

impl EngineGeometry {
    /// Cylinder `k`'s angle relative to the crank, rad: its throw's angle less its bank's, so
    /// the cylinder's own crank angle (0 at its top dead centre) is the engine crank angle plus
    /// this. The one place the kinematics, the gas, the pressure kinks and the top dead centres
    /// read it from, so they cannot disagree on where a cylinder is. 0 for a cylinder that does
    /// not exist or names no throw (refused by [`CrankTrain::new`]).
    pub fn cylinder_offset_rad(&self, k: usize) -> f64 {
        self.cylinders.get(k).map_or(0.0, |c| {
            self.throws.get(c.throw).map_or(0.0, |t| t.angle_rad) - c.bank_rad
        })
    }
}

/// Friction loads of one cylinder's joints (the signs of `mechanics::JointLoads`).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CylinderLoads {
    /// Torque on the rod from the big end (the crank receives the opposite), N m.
    pub big_end_torque_nm: f64,
    /// Torque on the piston from the small end (the rod receives the opposite), N m.
    pub small_end_torque_nm: f64,
    /// Force on the piston along its cylinder axis (+ towards the head) from the slide, N.
    pub slide_force_n: f64,
}

/// Friction loads of the whole train.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct TrainLoads {
    /// Torque on the crank from all main bearings together, N m.
    pub main_torque_nm: f64,
    /// Per cylinder.
    pub cylinders: Vec<CylinderLoads>,
}

/// One cylinder's reactions, forces in the global frame.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CylinderReactions {
    /// Force from the crank pin on the rod at the big end, N.
    pub big_end_n: Vector2<f64>,
    /// Force from the rod on the piston at the small end, N.
    pub small_end_n: Vector2<f64>,
    /// Lateral force from the cylinder wall on the piston (cylinder frame +x), N.
    pub slide_lateral_n: f64,
    /// Moment from the cylinder wall on the piston, N m.
    pub slide_moment_nm: f64,
}

/// The reactions of the whole train at one instant.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct TrainReactions {
    /// Force from the ground on the crank at each main bearing (statically determinate split
    /// per throw), N.
    pub mains_n: Vec<Vector2<f64>>,
    /// Their sum: the crank's whole main reaction, N.
    pub main_total_n: Vector2<f64>,
    /// Each throw's load on the mains before the split (its rods' big-end forces, its
    /// counterweights' inertia and weight, its share of the balanced crank's weight), N.
    pub throws_n: Vec<Vector2<f64>>,
    /// Per cylinder.
    pub cylinders: Vec<CylinderReactions>,
    /// Torque the drive applies to the crank (along theta), N m.
    pub drive_torque_nm: f64,
    /// Each throw's torque from its rods and counterweights (the big ends' friction and the
    /// pins' forces, the counterweights' weight), N m: the part of the drive torque each throw
    /// of an elastic crankshaft takes, its own inertia and the mains' friction aside.
    pub throw_torques_nm: Vec<f64>,
    /// Force the moving parts put on the block through the mains and the cylinder walls
    /// (the shaking force), N.
    pub block_force_n: Vector2<f64>,
}

/// One cylinder's kinematics at a crank angle and speed, in its own frame, with every
/// acceleration split into its part at zero crank acceleration and its rate per unit of it.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CylinderKinematics {
    /// Local crank angle (0 at this cylinder's TDC), rad.
    pub local_angle_rad: f64,
    /// Rod angle from the cylinder axis, rad.
    pub rod_angle_rad: f64,
    /// Rod angular velocity, rad/s.
    pub rod_rate_rad_s: f64,
    /// Piston pin along the axis from the crank centre, m.
    pub piston_position_m: f64,
    /// Piston speed along the axis (+ towards the head), m/s.
    pub piston_speed_m_s: f64,
    /// Known force on the piston along its axis (the gas force), N.
    pub piston_force_n: f64,
    // Affine parts (value at alpha = 0, per unit alpha), cylinder frame.
    pin: Vector2<f64>,
    rod_com: Vector2<f64>,
    small_end: Vector2<f64>,
    rod_acc: [f64; 2],
    com_acc: [Vector2<f64>; 2],
    piston_acc: [f64; 2],
}

/// The load-independent state of the train at one crank angle and speed.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct TrainKinematics {
    /// Crank angle, rad.
    pub theta: f64,
    /// Crank speed, rad/s.
    pub omega: f64,
    /// Each throw's angle and speed (rad, rad/s): the crank's own on a rigid crankshaft, its
    /// own twisted state on an elastic one.
    pub throws: Vec<(f64, f64)>,
    /// Per cylinder.
    pub cylinders: Vec<CylinderKinematics>,
}

/// Rotation of a cylinder frame into the global frame: cosine and sine of its bank angle.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Frame {
    c: f64,
    s: f64,
}

impl Frame {
    fn new(angle: f64) -> Self {
        Self {
            c: angle.cos(),
            s: angle.sin(),
        }
    }
    /// Local to global.
    fn to_global(self, v: Vector2<f64>) -> Vector2<f64> {
        Vector2::new(self.c * v.x - self.s * v.y, self.s * v.x + self.c * v.y)
    }
    /// Global to local.
    fn to_local(self, v: Vector2<f64>) -> Vector2<f64> {
        Vector2::new(self.c * v.x + self.s * v.y, -self.s * v.x + self.c * v.y)
    }
}

/// 2-D cross product (the z component).
fn cross(a: Vector2<f64>, b: Vector2<f64>) -> f64 {
    a.x * b.y - a.y * b.x
}

/// The crank train ready to solve.
#[derive(Debug, Clone)]
pub struct CrankTrain {
    geo: EngineGeometry,
    frames: Vec<Frame>,
    /// Each throw's two mains and the lever-rule weights of its load on them.
    split: Vec<[(usize, f64); 2]>,
    /// Moment of inertia about the axis: crank, counterweights and drive, kg m^2.
    j_axis: f64,
    /// The balanced crank mass's weight share of each throw, kg.
    mass_per_throw: f64,
}

impl CrankTrain {
    /// Build the train, checking the topology the mechanics relies on.
    pub fn new(geo: EngineGeometry) -> Result<Self, EngineError> {
        let mains = &geo.mains_axial_m;
        if mains.len() < 2
            || mains
                .windows(2)
                .any(|w| w[1].partial_cmp(&w[0]) != Some(std::cmp::Ordering::Greater))
        {
            return Err(EngineError::Mains);
        }
        let mut split = Vec::with_capacity(geo.throws.len());
        for (j, t) in geo.throws.iter().enumerate() {
            let z = t.axial_m;
            let inside = z > mains[0] && z < mains[mains.len() - 1];
            let apart = geo
                .throws
                .iter()
                .enumerate()
                .all(|(i, o)| i == j || o.axial_m != z);
            if !(inside && apart) {
                return Err(EngineError::ThrowPlace {
                    throw: j + 1,
                    axial_m: z,
                });
            }
            // The mains either side: the last at or before z, the first after it.
            let right = mains.partition_point(|m| *m <= z);
            let left = right - 1;
            let span = mains[right] - mains[left];
            let w_left = (mains[right] - z) / span;
            split.push([(left, w_left), (right, 1.0 - w_left)]);
        }
        for (k, c) in geo.cylinders.iter().enumerate() {
            if c.throw >= geo.throws.len() {
                return Err(EngineError::NoThrow {
                    cylinder: k + 1,
                    throw: c.throw + 1,
                    throws: geo.throws.len(),
                });
            }
            let reach = geo.crank_radius_m + (c.pin_offset_m + c.crank_offset_m).abs();
            if c.rod.length_m <= reach {
                return Err(EngineError::RodTooShort {
                    cylinder: k + 1,
                    length_m: c.rod.length_m,
                    reach_m: reach,
                });
            }
        }
        let cw: f64 = geo
            .throws
            .iter()
            .flat_map(|t| &t.counterweights)
            .map(|w| w.mass_kg * w.radius_m * w.radius_m)
            .sum();
        Ok(Self {
            frames: geo
                .cylinders
                .iter()
                .map(|c| Frame::new(c.bank_rad))
                .collect(),
            split,
            j_axis: geo.crank_inertia_kg_m2 + cw + geo.drive_inertia_kg_m2,
            mass_per_throw: geo.crank_mass_kg / geo.throws.len().max(1) as f64,
            geo,
        })
    }

    /// The geometry the train was built from.
    pub fn geometry(&self) -> &EngineGeometry {
        &self.geo
    }

    /// Moment of inertia of the crank about its axis (counterweights and drive included).
    pub fn crank_inertia_about_axis(&self) -> f64 {
        self.j_axis
    }

    /// Each throw's own moment of inertia about the axis on an elastic crankshaft, kg m^2:
    /// an equal share of the balanced crank's and its webs' counterweights (the drive's
    /// inertia sits on the flywheel's node instead).
    pub fn throw_inertias(&self) -> Vec<f64> {
        let n = self.geo.throws.len().max(1) as f64;
        self.geo
            .throws
            .iter()
            .map(|t| {
                self.geo.crank_inertia_kg_m2 / n
                    + t.counterweights
                        .iter()
                        .map(|w| w.mass_kg * w.radius_m * w.radius_m)
                        .sum::<f64>()
            })
            .collect()
    }

    /// Each throw's two mains (0-based) and the share of its load each carries.
    pub fn main_split(&self) -> &[[(usize, f64); 2]] {
        &self.split
    }

    /// Kinetic plus potential energy of the moving parts at crank angle `theta` and speed
    /// `omega`, J (heights from the crank centre): what the motor's work changes over a
    /// transient run, for its energy balance.
    pub fn mechanical_energy(&self, theta: f64, omega: f64) -> f64 {
        self.twisted_mechanical_energy(theta, omega, &[], None)
    }

    /// [`CrankTrain::mechanical_energy`] of an elastic crankshaft: throw `j` turned by
    /// `twist[j]` (angle, speed) from `theta` and `omega`, turning with its own inertia
    /// `inertias[j]` (kg m^2; `None`: the rigid crank's inertia about the axis).
    pub fn twisted_mechanical_energy(
        &self,
        theta: f64,
        omega: f64,
        twist: &[(f64, f64)],
        inertias: Option<&[f64]>,
    ) -> f64 {
        let g = self.geo.gravity_m_s2;
        let mut kin = TrainKinematics::default();
        self.twisted_kinematics_into(theta, omega, twist, &[], &mut kin);
        let mut energy = match inertias {
            None => 0.5 * self.j_axis * omega * omega,
            Some(j) => (j.iter().zip(&kin.throws))
                .map(|(j, (_, w))| 0.5 * j * w * w)
                .sum(),
        };
        for (t, (theta, _)) in self.geo.throws.iter().zip(&kin.throws) {
            for cw in &t.counterweights {
                energy += cw.mass_kg * g * cw.radius_m * (theta + t.angle_rad + cw.angle_rad).cos();
            }
        }
        let r = self.geo.crank_radius_m;
        for ((c, ck), fr) in self
            .geo
            .cylinders
            .iter()
            .zip(&kin.cylinders)
            .zip(&self.frames)
        {
            let omega = kin.throws[c.throw].1;
            let (s, co) = ck.local_angle_rad.sin_cos();
            let (sp, cp) = ck.rod_angle_rad.sin_cos();
            let rate = ck.rod_rate_rad_s;
            // The rod centre moves with the pin and turns about it.
            let v_pin = Vector2::new(-r * co * omega, -r * s * omega);
            let v_com = v_pin + Vector2::new(-cp * rate, -sp * rate) * c.rod.com_from_big_end_m;
            energy += 0.5 * c.rod.mass_kg * v_com.norm_squared()
                + 0.5 * c.rod.inertia_kg_m2 * rate * rate
                + 0.5 * c.piston_mass_kg * ck.piston_speed_m_s * ck.piston_speed_m_s
                + g * (c.rod.mass_kg * fr.to_global(ck.rod_com).y
                    + c.piston_mass_kg * fr.to_global(ck.small_end).y);
        }
        energy
    }

    /// Kinematics at crank angle `theta` and speed `omega`, with the known axial force
    /// `piston_forces_n[k]` on each piston (gas; missing entries are zero).
    pub fn kinematics(&self, theta: f64, omega: f64, piston_forces_n: &[f64]) -> TrainKinematics {
        let mut k = TrainKinematics::default();
        self.kinematics_into(theta, omega, piston_forces_n, &mut k);
        k
    }

    /// [`CrankTrain::kinematics`] into a recycled `out` (no allocation once it has the size).
    pub fn kinematics_into(
        &self,
        theta: f64,
        omega: f64,
        piston_forces_n: &[f64],
        out: &mut TrainKinematics,
    ) {
        self.twisted_kinematics_into(theta, omega, &[], piston_forces_n, out);
    }

    /// [`CrankTrain::kinematics_into`] on an elastic crankshaft: throw `j` turned by
    /// `twist[j]` (angle, rad, and speed, rad/s) from the crank's `theta` and `omega`; an empty
    /// `twist` is the rigid crank.
    pub fn twisted_kinematics_into(
        &self,
        theta: f64,
        omega: f64,
        twist: &[(f64, f64)],
        piston_forces_n: &[f64],
        out: &mut TrainKinematics,
    ) {
        out.theta = theta;
        out.omega = omega;
        out.throws.clear();
        if twist.is_empty() {
            out.throws.resize(self.geo.throws.len(), (theta, omega));
        } else {
            out.throws.extend((0..self.geo.throws.len()).map(|j| {
                let (d, dw) = twist.get(j).copied().unwrap_or((0.0, 0.0));
                (theta + d, omega + dw)
            }));
        }
        out.cylinders.clear();
        let r = self.geo.crank_radius_m;
        for (k, c) in self.geo.cylinders.iter().enumerate() {
            let (theta, omega) = out.throws.get(c.throw).copied().unwrap_or((theta, omega));
            let local = theta + self.geo.cylinder_offset_rad(k);
            let (s, co) = local.sin_cos();
            let l = c.rod.length_m;
            let a = c.rod.com_from_big_end_m;
            let e = c.pin_offset_m + c.crank_offset_m;
            let pin = Vector2::new(-r * s, r * co);
            let sin_psi = -(e + r * s) / l;
            let cos_psi = (1.0 - sin_psi * sin_psi).sqrt();
            let psi = sin_psi.atan2(cos_psi);
            let psi_d = -r * co * omega / (l * cos_psi);
            // psi'' = (r s w^2 - r c alpha + l sin(psi) psi'^2) / (l cos psi): affine in alpha.
            let psi_dd = [
                (r * s * omega * omega + l * sin_psi * psi_d * psi_d) / (l * cos_psi),
                -r * co / (l * cos_psi),
            ];
            // Pin acceleration: r(-c alpha + s w^2, -s alpha - c w^2).
            let pin_acc = [
                Vector2::new(r * s * omega * omega, -r * co * omega * omega),
                Vector2::new(-r * co, -r * s),
            ];
            // u = (-sin psi, cos psi); u'' = (-cos psi psi'' + sin psi psi'^2,
            //                                  -sin psi psi'' - cos psi psi'^2).
            let u_dd = |psi_dd: f64, with_rate: bool| {
                let w2 = if with_rate { psi_d * psi_d } else { 0.0 };
                Vector2::new(
                    -cos_psi * psi_dd + sin_psi * w2,
                    -sin_psi * psi_dd - cos_psi * w2,
                )
            };
            let com_acc = [
                pin_acc[0] + u_dd(psi_dd[0], true) * a,
                pin_acc[1] + u_dd(psi_dd[1], false) * a,
            ];
            let piston_acc = [
                pin_acc[0].y + l * u_dd(psi_dd[0], true).y,
                pin_acc[1].y + l * u_dd(psi_dd[1], false).y,
            ];
            let u = Vector2::new(-sin_psi, cos_psi);
            out.cylinders.push(CylinderKinematics {
                local_angle_rad: local,
                rod_angle_rad: psi,
                rod_rate_rad_s: psi_d,
                piston_position_m: r * co + l * cos_psi,
                piston_speed_m_s: -r * s * omega - l * sin_psi * psi_d,
                piston_force_n: piston_forces_n.get(k).copied().unwrap_or(0.0),
                pin,
                rod_com: pin + u * a,
                small_end: pin + u * l,
                rod_acc: psi_dd,
                com_acc,
                piston_acc,
            });
        }
    }

    /// Reactions at crank acceleration `alpha` under the friction `loads` (missing cylinder
    /// entries are zero).
    pub fn reactions(&self, k: &TrainKinematics, alpha: f64, loads: &TrainLoads) -> TrainReactions {
        let mut out = TrainReactions::default();
        self.reactions_into(k, alpha, loads, &mut out);
        out
    }

    /// [`CrankTrain::reactions`] into a recycled `out`.
    pub fn reactions_into(
        &self,
        kin: &TrainKinematics,
        alpha: f64,
        loads: &TrainLoads,
        out: &mut TrainReactions,
    ) {
        self.reactions_with(kin, alpha, |_| alpha, loads, out);
    }

    /// [`CrankTrain::reactions_into`] on an elastic crankshaft: throw `j` at acceleration
    /// `alphas[j]` (rad/s^2). The drive torque is then the sum of the throws' torques at their
    /// own accelerations with each throw's `inertias[j]` (kg m^2) and its share of the mains'
    /// friction `main_torques_nm[j]` (N m).
    pub fn twisted_reactions_into(
        &self,
        kin: &TrainKinematics,
        (alphas, inertias, main_torques_nm): (&[f64], &[f64], &[f64]),
        loads: &TrainLoads,
        out: &mut TrainReactions,
    ) {
        let alpha_of = |j: usize| alphas.get(j).copied().unwrap_or(0.0);
        self.reactions_with(kin, alpha_of(0), alpha_of, loads, out);
        out.drive_torque_nm = out
            .throw_torques_nm
            .iter()
            .enumerate()
            .map(|(j, t)| {
                inertias.get(j).copied().unwrap_or(0.0) * alpha_of(j)
                    - main_torques_nm.get(j).copied().unwrap_or(0.0)
                    + t
            })
            .sum();
    }

    /// The reactions with throw `j` at acceleration `alpha_of(j)`; the drive torque the rigid
    /// crank's at `alpha`.
    #[inline]
    fn reactions_with(
        &self,
        kin: &TrainKinematics,
        alpha: f64,
        alpha_of: impl Fn(usize) -> f64,
        loads: &TrainLoads,
        out: &mut TrainReactions,
    ) {
        let g = self.geo.gravity_m_s2;
        let gravity = Vector2::new(0.0, -g);
        out.cylinders.clear();
        out.mains_n.clear();
        out.mains_n
            .resize(self.geo.mains_axial_m.len(), Vector2::zeros());
        let mut drive = self.j_axis * alpha - loads.main_torque_nm;
        let mut block = Vector2::zeros();
        // Each throw's load on the crank's mains, before the split: its share of the balanced
        // mass's weight, its counterweights' inertia and weight, its rods' big-end forces.
        // The recycled buffer: no allocation once it has the size.
        let mut throw_loads = std::mem::take(&mut out.throws_n);
        let mut throw_torques = std::mem::take(&mut out.throw_torques_nm);
        throw_loads.clear();
        throw_torques.clear();
        for (j, t) in self.geo.throws.iter().enumerate() {
            let mut f = -gravity * self.mass_per_throw;
            let mut torque = 0.0;
            let (theta, omega) = kin.throws.get(j).copied().unwrap_or((kin.theta, kin.omega));
            let a = alpha_of(j);
            for cw in &t.counterweights {
                let ang = theta + t.angle_rad + cw.angle_rad;
                let (s, c) = ang.sin_cos();
                let pos = Vector2::new(-s, c) * cw.radius_m;
                let w2 = omega * omega;
                // d2/dt2 of R(-sin, cos): R(-c a + s w^2, -s a - c w^2).
                let acc = Vector2::new(-c * a + s * w2, -s * a - c * w2) * cw.radius_m;
                f += (acc - gravity) * cw.mass_kg;
                let weight = cross(pos, gravity * cw.mass_kg);
                drive -= weight;
                torque -= weight;
            }
            throw_loads.push(f);
            throw_torques.push(torque);
        }
        for (ki, (c, ck)) in self.geo.cylinders.iter().zip(&kin.cylinders).enumerate() {
            let fr = self.frames[ki];
            let ld = loads.cylinders.get(ki).copied().unwrap_or_default();
            let f = self.cylinder_forces(ki, ck, alpha_of(c.throw), &ld);
            let f_b_glob = fr.to_global(f.big_end);
            let pin_glob = fr.to_global(ck.pin);
            let on_pin = ld.big_end_torque_nm + cross(pin_glob, f_b_glob);
            drive += on_pin;
            throw_torques[c.throw] += on_pin;
            throw_loads[c.throw] += f_b_glob;
            block -= fr.to_global(Vector2::new(f.lateral, ld.slide_force_n));
            out.cylinders.push(CylinderReactions {
                big_end_n: f_b_glob,
                small_end_n: fr.to_global(f.small_end),
                slide_lateral_n: f.lateral,
                slide_moment_nm: -ld.small_end_torque_nm + c.pin_offset_m * f.axial,
            });
        }
        let mut total = Vector2::zeros();
        for (load, split) in throw_loads.iter().zip(&self.split) {
            for (main, w) in split {
                out.mains_n[*main] += load * *w;
            }
            total += load;
        }
        // The balanced mass without throws (a crank with no throw) still weighs on the mains.
        if self.geo.throws.is_empty() {
            total -= gravity * self.geo.crank_mass_kg;
        }
        out.throws_n = throw_loads;
        out.throw_torques_nm = throw_torques;
        out.main_total_n = total;
        out.block_force_n = block - total;
        out.drive_torque_nm = drive;
    }

    /// The crank acceleration at which the drive torque equals `torque` under `loads`.
    pub fn alpha_for_torque(&self, kin: &TrainKinematics, torque: f64, loads: &TrainLoads) -> f64 {
        let t0 = self.drive_torque(kin, 0.0, loads);
        let t1 = self.drive_torque(kin, 1.0, loads);
        // d(drive torque)/d(alpha) is the train's effective inertia at this angle (> 0).
        (torque - t0) / (t1 - t0)
    }

    /// The drive torque alone at crank acceleration `alpha` under `loads` (what
    /// [`CrankTrain::reactions_into`] gives as `drive_torque_nm`, without the main split).
    pub fn drive_torque(&self, kin: &TrainKinematics, alpha: f64, loads: &TrainLoads) -> f64 {
        let gravity = Vector2::new(0.0, -self.geo.gravity_m_s2);
        let mut drive = self.j_axis * alpha - loads.main_torque_nm;
        for t in &self.geo.throws {
            for cw in &t.counterweights {
                let (s, c) = (kin.theta + t.angle_rad + cw.angle_rad).sin_cos();
                drive -= cross(Vector2::new(-s, c) * cw.radius_m, gravity * cw.mass_kg);
            }
        }
        for (ki, ck) in kin.cylinders.iter().enumerate() {
            let fr = self.frames[ki];
            let ld = loads.cylinders.get(ki).copied().unwrap_or_default();
            let f = self.cylinder_forces(ki, ck, alpha, &ld);
            drive += ld.big_end_torque_nm + cross(fr.to_global(ck.pin), fr.to_global(f.big_end));
        }
        drive
    }

    /// Cylinder `ki`'s joint forces in its own frame at crank acceleration `alpha` under its
    /// friction loads `ld` (see `docs/engines.md`, Mechanics): the piston's axial balance gives
    /// the small end's axial force, the rod's moment about the big end its lateral one, then
    /// the wall's side thrust and the big-end force.
    #[inline]
    fn cylinder_forces(
        &self,
        ki: usize,
        ck: &CylinderKinematics,
        alpha: f64,
        ld: &CylinderLoads,
    ) -> CylinderForces {
        let c = &self.geo.cylinders[ki];
        let g_loc = self.frames[ki].to_local(Vector2::new(0.0, -self.geo.gravity_m_s2));
        let (m_r, m_p) = (c.rod.mass_kg, c.piston_mass_kg);
        let a_g = ck.com_acc[0] + ck.com_acc[1] * alpha;
        let a_s = Vector2::new(0.0, ck.piston_acc[0] + ck.piston_acc[1] * alpha);
        let psi_dd = ck.rod_acc[0] + ck.rod_acc[1] * alpha;
        let axial = ck.piston_force_n + ld.slide_force_n;
        let fs_y = m_p * (a_s.y - g_loc.y) - axial;
        let d = ck.small_end - ck.pin;
        let h = ck.rod_com - ck.pin;
        let rhs = ld.big_end_torque_nm
            - ld.small_end_torque_nm
            - c.rod.inertia_kg_m2 * psi_dd
            - cross(h, (a_g - g_loc) * m_r);
        let fs_x = (d.x * fs_y - rhs) / d.y;
        let small_end = Vector2::new(fs_x, fs_y);
        CylinderForces {
            small_end,
            lateral: m_p * (a_s.x - g_loc.x) - fs_x,
            big_end: (a_g - g_loc) * m_r + small_end,
            axial,
        }
    }
}

/// One cylinder's joint forces in its own frame (see `CrankTrain::cylinder_forces`).
struct CylinderForces {
    /// From the rod on the piston, N.
    small_end: Vector2<f64>,
    /// From the wall on the piston, across the axis, N.
    lateral: f64,
    /// From the crank pin on the rod, N.
    big_end: Vector2<f64>,
    /// Known axial force on the piston (gas plus slide friction), N.
    axial: f64,
}

/// The crank train a rig's `[engine]` describes (`None` for the single-cylinder rig), from the
/// validated model: the crank's balanced part from `[bodies.crank]`, each rod from
/// `[bodies.rod]` with its own overrides, the piston from `[bodies.piston]`, the PI drive's
/// motor inertia reflected through the belt.
pub fn geometry(f: &crate::model::RigFile) -> Option<EngineGeometry> {
    let e = f.engine.as_ref()?;
    let c = &f.bodies.crank;
    let r = &f.bodies.rod;
    let base_rod = RodGeometry {
        mass_kg: r.mass_kg * r.mass_scale,
        inertia_kg_m2: r.inertia_kg_m2 * r.inertia_scale,
        length_m: r.length_m,
        com_from_big_end_m: r.com_from_big_end_m,
    };
    let rod_of = |k: usize| {
        let spec = e.rods.iter().find(|s| s.cylinder == k + 1);
        spec.map_or(base_rod, |s| RodGeometry {
            mass_kg: s.mass_kg.map_or(base_rod.mass_kg, |m| m * r.mass_scale),
            inertia_kg_m2: s
                .inertia_kg_m2
                .map_or(base_rod.inertia_kg_m2, |j| j * r.inertia_scale),
            length_m: s.length_m.unwrap_or(base_rod.length_m),
            com_from_big_end_m: s.com_from_big_end_m.unwrap_or(base_rod.com_from_big_end_m),
        })
    };
    Some(EngineGeometry {
        crank_radius_m: f.geometry.crank_radius_m,
        crank_mass_kg: c.mass_kg * c.mass_scale,
        crank_inertia_kg_m2: c.inertia_kg_m2 * c.inertia_scale,
        drive_inertia_kg_m2: f.drive.reflected_inertia_kg_m2(),
        gravity_m_s2: if f.geometry.gravity {
            crate::model::GRAVITY_M_S2
        } else {
            0.0
        },
        mains_axial_m: e.mains.iter().map(|m| m.axial_position_m).collect(),
        throws: e
            .throws
            .iter()
            .map(|t| ThrowGeometry {
                angle_rad: t.angle_deg.to_radians(),
                axial_m: t.axial_position_m,
                counterweights: t
                    .counterweights
                    .iter()
                    .map(|w| Counterweight {
                        mass_kg: w.mass_kg * c.mass_scale,
                        radius_m: w.radius_m,
                        angle_rad: w.angle_deg.to_radians(),
                    })
                    .collect(),
            })
            .collect(),
        cylinders: e
            .cylinders
            .iter()
            .enumerate()
            .map(|(k, s)| CylinderGeometry {
                throw: s.throw.saturating_sub(1),
                bank_rad: s.bank_angle_deg(e.v_angle_deg).to_radians(),
                pin_offset_m: s.pin_offset_m,
                crank_offset_m: s.crank_offset_m,
                rod: rod_of(k),
                piston_mass_kg: f.bodies.piston.mass_kg * f.bodies.piston.mass_scale,
            })
            .collect(),
    })
}

/// Each cylinder's top dead centre in engine crank angle, rad: where its pin meets its axis
/// (`bank - throw angle`, minus [`EngineGeometry::cylinder_offset_rad`]).
pub fn top_dead_centres(geo: &EngineGeometry) -> Vec<f64> {
    (0..geo.cylinders.len())
        .map(|k| -geo.cylinder_offset_rad(k))
        .collect()
}

/// The most cylinders [`cylinder_phases`] takes (it tries every choice of firing TDCs).
pub const MAX_CYLINDERS: usize = 16;

/// Each cylinder's 4-stroke phase, rad (0: its local angle 0 is the gas-exchange TDC; 2 pi: the
/// firing TDC), from the firing order `order` (1-based cylinder numbers). `tdc_rad[k]` is the
/// engine crank angle of cylinder k's top dead centre (`bank - throw angle`). The first
/// cylinder of the order takes `first_phase_rad`; every other cylinder has two TDCs in a
/// 720-degree cycle and fires at one of them. Of the choices that make the cylinders fire in
/// the given order within one cycle (every interval above zero), the most even one is taken
/// (the smallest largest interval, then the smallest sum of squared intervals): the regular
/// 180 degrees of a flat-plane inline-4, 270-450 of a 90-degree V-twin.
pub fn cylinder_phases(
    tdc_rad: &[f64],
    order: &[usize],
    first_phase_rad: f64,
) -> Result<Vec<f64>, EngineError> {
    let n = tdc_rad.len();
    let mut seen = vec![false; n];
    let permutation = order.len() == n
        && n <= MAX_CYLINDERS
        && order
            .iter()
            .all(|&c| (1..=n).contains(&c) && !std::mem::replace(&mut seen[c - 1], true));
    if !permutation {
        return Err(EngineError::NotPermutation {
            order: order.to_vec(),
            cylinders: n,
        });
    }
    let cycle = 2.0 * TAU;
    let wrap = |a: f64| a - cycle * (a / cycle).floor();
    // Cylinder k's cycle angle at engine angle theta is (theta - tdc_k) + phase_k; it fires
    // where that is 2 pi (mod 4 pi).
    let fire = |k: usize, phase: f64| wrap(TAU - phase + tdc_rad[k]);
    let first = order[0] - 1;
    let t0 = fire(first, first_phase_rad);
    // Firings closer than this are one instant (rounding of the angles).
    let eps = 1e-9;
    let mut best: Option<(f64, f64, u32)> = None;
    for choice in 0..1_u32 << (n - 1) {
        let mut last = 0.0;
        let (mut largest, mut squares, mut ok) = (0.0_f64, 0.0, true);
        for (i, &c) in order[1..].iter().enumerate() {
            let phase = if choice >> i & 1 == 1 { TAU } else { 0.0 };
            let at = wrap(fire(c - 1, phase) - t0);
            let gap = at - last;
            if gap < eps {
                ok = false;
                break;
            }
            largest = largest.max(gap);
            squares += gap * gap;
            last = at;
        }
        let back = cycle - last;
        if !ok || back < eps {
            continue;
        }
        largest = largest.max(back);
        squares += back * back;
        let better = best
            .is_none_or(|(l, s, _)| largest < l - eps || (largest < l + eps && squares < s - eps));
        if better {
            best = Some((largest, squares, choice));
        }
    }
    let Some((_, _, choice)) = best else {
        return Err(EngineError::OrderMisfit {
            order: order.to_vec(),
            tdc_deg: tdc_rad
                .iter()
                .map(|t| wrap(*t).to_degrees() % 360.0)
                .collect(),
        });
    };
    let mut phases = vec![0.0; n];
    phases[first] = first_phase_rad;
    for (i, &c) in order[1..].iter().enumerate() {
        phases[c - 1] = if choice >> i & 1 == 1 { TAU } else { 0.0 };
    }
    Ok(phases)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mechanics::{JointLoads, Mechanism, RigGeometry};
    use std::f64::consts::PI;

    /// A rod whose two-point-mass model is exact: I = m a (l - a).
    fn two_mass_rod(m: f64, l: f64, a: f64) -> RodGeometry {
        RodGeometry {
            mass_kg: m,
            inertia_kg_m2: m * a * (l - a),
            length_m: l,
            com_from_big_end_m: a,
        }
    }

    fn cylinder(throw: usize, bank_deg: f64, rod: RodGeometry, m_p: f64) -> CylinderGeometry {
        CylinderGeometry {
            throw,
            bank_rad: bank_deg.to_radians(),
            pin_offset_m: 0.0,
            crank_offset_m: 0.0,
            rod,
            piston_mass_kg: m_p,
        }
    }

    fn throw(angle_deg: f64, z: f64) -> ThrowGeometry {
        ThrowGeometry {
            angle_rad: angle_deg.to_radians(),
            axial_m: z,
            counterweights: Vec::new(),
        }
    }

    /// An inline-4 with a flat-plane crank (0-180-180-0), five mains.
    fn inline4(gravity: f64) -> (CrankTrain, f64, f64, f64) {
        let (r, l, a, m_r, m_p) = (0.0405, 0.138, 0.046, 0.52, 0.36);
        let rod = two_mass_rod(m_r, l, a);
        let throws = [0.0, 180.0, 180.0, 0.0]
            .iter()
            .enumerate()
            .map(|(i, ang)| throw(*ang, 0.045 + 0.09 * i as f64))
            .collect();
        let geo = EngineGeometry {
            crank_radius_m: r,
            crank_mass_kg: 9.0,
            crank_inertia_kg_m2: 0.012,
            drive_inertia_kg_m2: 0.0,
            gravity_m_s2: gravity,
            mains_axial_m: (0..5).map(|i| 0.09 * i as f64).collect(),
            throws,
            cylinders: (0..4).map(|k| cylinder(k, 0.0, rod, m_p)).collect(),
        };
        let m_rec = m_p + m_r * a / l;
        (CrankTrain::new(geo).expect("valid"), r, l, m_rec)
    }

    fn frictionless(n: usize) -> TrainLoads {
        TrainLoads {
            main_torque_nm: 0.0,
            cylinders: vec![CylinderLoads::default(); n],
        }
    }

    /// Fourier coefficient of `f` sampled at `n` equal steps over one revolution, order `k`:
    /// (cos part, sin part).
    fn fourier(f: &[f64], k: f64) -> (f64, f64) {
        let n = f.len() as f64;
        f.iter().enumerate().fold((0.0, 0.0), |(c, s), (i, v)| {
            let t = TAU * i as f64 / n;
            (
                c + 2.0 * v * (k * t).cos() / n,
                s + 2.0 * v * (k * t).sin() / n,
            )
        })
    }

    #[test]
    fn inline4_flat_crank_has_no_primary_and_the_known_secondary_force() {
        let (train, r, l, m_rec) = inline4(0.0);
        let omega = 600.0;
        let n = 720;
        let lambda = r / l;
        let mut fy = Vec::with_capacity(n);
        let mut fx_max: f64 = 0.0;
        for i in 0..n {
            let theta = TAU * i as f64 / n as f64;
            let kin = train.kinematics(theta, omega, &[]);
            let re = train.reactions(&kin, 0.0, &frictionless(4));
            fy.push(re.block_force_n.y);
            fx_max = fx_max.max(re.block_force_n.x.abs());
            // The shaking force of a two-mass rod, written out independently: the reciprocating
            // masses' inertia force, the exact series of the piston acceleration
            // -r w^2 (cos t + A2 cos 2t - A4 cos 4t + A6 cos 6t ...) summed over the four
            // cylinders (1 and 4 at t, 2 and 3 at t + pi): the odd orders cancel.
            let a2 = lambda + lambda.powi(3) / 4.0 + 15.0 * lambda.powi(5) / 128.0;
            let a4 = lambda.powi(3) / 4.0 + 3.0 * lambda.powi(5) / 16.0;
            let a6 = 9.0 * lambda.powi(5) / 128.0;
            let expected = 4.0
                * m_rec
                * r
                * omega
                * omega
                * (a2 * (2.0 * theta).cos() - a4 * (4.0 * theta).cos() + a6 * (6.0 * theta).cos());
            let scale = 4.0 * m_rec * r * omega * omega * lambda;
            // The series' first omitted terms are of order lambda^7 r w^2 (coefficients below
            // 0.1): within lambda^6 of the secondary amplitude.
            assert!(
                (re.block_force_n.y - expected).abs() < scale * lambda.powi(6),
                "theta {theta}: {} vs {expected}",
                re.block_force_n.y
            );
        }
        let secondary = 4.0 * m_rec * r * omega * omega * lambda;
        // Primary: zero to rounding. Secondary: 4 m_rec r w^2 (r/l) cos 2 theta, to the series'
        // next term in lambda^2 (the exact second-order amplitude is lambda + lambda^3/4 + ...).
        let (c1, s1) = fourier(&fy, 1.0);
        assert!(
            c1.abs().max(s1.abs()) < 1e-9 * secondary,
            "primary {c1} {s1}"
        );
        let (c2, s2) = fourier(&fy, 2.0);
        assert!(s2.abs() < 1e-9 * secondary);
        let rel = (c2 - secondary) / secondary;
        assert!(
            rel > 0.0 && rel < lambda * lambda / 4.0 * 1.1,
            "second order {c2} vs {secondary}: {rel}"
        );
        assert!(fx_max < 1e-9 * secondary, "lateral shaking {fx_max}");
    }

    #[test]
    fn frictionless_engines_have_zero_mean_drive_torque() {
        let (i4, ..) = inline4(9.80665);
        // A 90-degree V-twin on one throw, offsets and a counterweight, and a boxer twin.
        let rod = RodGeometry {
            mass_kg: 0.45,
            inertia_kg_m2: 1.1e-3,
            length_m: 0.13,
            com_from_big_end_m: 0.04,
        };
        let mut v_cyl = [cylinder(0, -45.0, rod, 0.5), cylinder(0, 45.0, rod, 0.5)];
        v_cyl[0].pin_offset_m = 0.001;
        v_cyl[1].crank_offset_m = -0.002;
        let mut t = throw(0.0, 0.05);
        t.counterweights.push(Counterweight {
            mass_kg: 0.8,
            radius_m: 0.035,
            angle_rad: PI,
        });
        let v_twin = CrankTrain::new(EngineGeometry {
            crank_radius_m: 0.04,
            crank_mass_kg: 6.0,
            crank_inertia_kg_m2: 0.01,
            drive_inertia_kg_m2: 0.0,
            gravity_m_s2: 9.80665,
            mains_axial_m: vec![0.0, 0.1],
            throws: vec![t],
            cylinders: v_cyl.to_vec(),
        })
        .expect("valid");
        let boxer = CrankTrain::new(EngineGeometry {
            crank_radius_m: 0.035,
            crank_mass_kg: 5.0,
            crank_inertia_kg_m2: 0.008,
            drive_inertia_kg_m2: 0.0,
            gravity_m_s2: 9.80665,
            mains_axial_m: vec![0.0, 0.06, 0.12],
            throws: vec![throw(0.0, 0.03), throw(180.0, 0.09)],
            cylinders: vec![cylinder(0, 90.0, rod, 0.4), cylinder(1, -90.0, rod, 0.4)],
        })
        .expect("valid");
        for (name, train) in [("inline-4", &i4), ("V-twin", &v_twin), ("boxer", &boxer)] {
            let n = train.geometry().cylinders.len();
            let samples = 1440;
            let (mut sum, mut peak) = (0.0, 0.0_f64);
            for i in 0..samples {
                let theta = TAU * i as f64 / samples as f64;
                let kin = train.kinematics(theta, 700.0, &[]);
                let t = train.reactions(&kin, 0.0, &frictionless(n)).drive_torque_nm;
                sum += t;
                peak = peak.max(t.abs());
            }
            let mean = sum / samples as f64;
            assert!(
                peak > 1.0,
                "{name}: an inertia torque to compare with ({peak})"
            );
            assert!(
                mean.abs() < 1e-9 * peak,
                "{name}: mean {mean} of peak {peak}"
            );
        }
    }

    #[test]
    fn inline4_torque_ripple_repeats_every_half_revolution() {
        let (train, ..) = inline4(9.80665);
        let mut peak = 0.0_f64;
        for i in 0..360 {
            let theta = (i as f64).to_radians();
            let t = |th: f64| {
                let kin = train.kinematics(th, 800.0, &[]);
                train
                    .reactions(&kin, 150.0, &frictionless(4))
                    .drive_torque_nm
            };
            let (a, b) = (t(theta), t(theta + PI));
            peak = peak.max(a.abs());
            assert!(
                (a - b).abs() < 1e-9 * (1.0 + a.abs()),
                "{theta}: {a} vs {b}"
            );
        }
        assert!(peak > 1.0);
    }

    /// The thesis rig's mechanism and the same single-throw engine in the new description.
    fn single_throw_pair(share_a: f64) -> (Mechanism, CrankTrain) {
        let (mu, ru, m_bal) = (0.4, 0.03, 3.0);
        let m_crank = m_bal + mu;
        let offset = mu * ru / m_crank;
        let (j_bal, drive) = (0.004, 0.0007);
        let geo = RigGeometry {
            crank_radius_m: 0.0269,
            rod_length_m: 0.105,
            rod_com_from_big_end_m: 0.035,
            crank_inertia_kg_m2: j_bal + mu * ru * ru - m_crank * offset * offset,
            crank_mass_kg: m_crank,
            crank_com_offset_m: offset,
            crank_com_angle_rad: 2.9,
            rod_mass_kg: 0.1748,
            rod_inertia_kg_m2: 261.8e-6,
            piston_mass_kg: 0.27,
            gravity_m_s2: 9.80665,
            drive_inertia_kg_m2: drive,
        };
        let train = CrankTrain::new(EngineGeometry {
            crank_radius_m: geo.crank_radius_m,
            crank_mass_kg: m_bal,
            crank_inertia_kg_m2: j_bal,
            drive_inertia_kg_m2: drive,
            gravity_m_s2: geo.gravity_m_s2,
            mains_axial_m: vec![0.0, 1.0],
            throws: vec![ThrowGeometry {
                angle_rad: 0.0,
                axial_m: 1.0 - share_a,
                counterweights: vec![Counterweight {
                    mass_kg: mu,
                    radius_m: ru,
                    angle_rad: 2.9,
                }],
            }],
            cylinders: vec![cylinder(
                0,
                0.0,
                RodGeometry {
                    mass_kg: geo.rod_mass_kg,
                    inertia_kg_m2: geo.rod_inertia_kg_m2,
                    length_m: geo.rod_length_m,
                    com_from_big_end_m: geo.rod_com_from_big_end_m,
                },
                geo.piston_mass_kg,
            )],
        })
        .expect("valid");
        (Mechanism::new(geo), train)
    }

    #[test]
    fn single_throw_engine_equals_the_mechanism() {
        let share_a = 0.3;
        let (mech, train) = single_throw_pair(share_a);
        let loads = JointLoads {
            main_torque_nm: -0.05,
            big_end_torque_nm: 0.02,
            small_end_torque_nm: -0.01,
            slide_force_n: 3.0,
        };
        let train_loads = TrainLoads {
            main_torque_nm: loads.main_torque_nm,
            cylinders: vec![CylinderLoads {
                big_end_torque_nm: loads.big_end_torque_nm,
                small_end_torque_nm: loads.small_end_torque_nm,
                slide_force_n: loads.slide_force_n,
            }],
        };
        let close = |a: f64, b: f64, scale: f64, what: &str| {
            assert!((a - b).abs() <= 1e-9 * scale, "{what}: {a} vs {b}");
        };
        for i in 0..72 {
            let theta = (5.0 * i as f64 + 0.3).to_radians();
            let (omega, alpha, gas) = (900.0, -350.0, 1200.0 * (i as f64 * 0.7).sin());
            let k = mech.kinematics_with_piston_force(theta, omega, gas);
            let re = k.reactions(alpha, &loads);
            let tk = train.kinematics(theta, omega, &[gas]);
            let tr = train.reactions(&tk, alpha, &train_loads);
            let scale = re.main_n.norm().max(re.big_end_n.norm()).max(1.0);
            for (axis, (a, b)) in [
                ("x", (re.main_n.x, tr.main_total_n.x)),
                ("y", (re.main_n.y, tr.main_total_n.y)),
            ] {
                close(a, b, scale, &format!("main {axis} at {theta}"));
            }
            // Today's split: each main its `load_share` of the whole reaction.
            close(tr.mains_n[0].x, share_a * re.main_n.x, scale, "main_a x");
            close(tr.mains_n[0].y, share_a * re.main_n.y, scale, "main_a y");
            close(
                tr.mains_n[1].y,
                (1.0 - share_a) * re.main_n.y,
                scale,
                "main_b y",
            );
            let c = &tr.cylinders[0];
            close(c.big_end_n.x, re.big_end_n.x, scale, "big end x");
            close(c.big_end_n.y, re.big_end_n.y, scale, "big end y");
            close(c.small_end_n.x, re.small_end_n.x, scale, "small end x");
            close(c.small_end_n.y, re.small_end_n.y, scale, "small end y");
            close(c.slide_lateral_n, re.slide_lateral_n, scale, "slide");
            close(c.slide_moment_nm, re.slide_moment_nm, 1.0, "slide moment");
            close(
                tr.drive_torque_nm,
                re.drive_torque_nm,
                scale * 0.03,
                "drive torque",
            );
            // A torque-driven crank: the same acceleration for the same torque.
            let a_m = k.alpha_for_torque(2.0, &loads);
            let a_t = train.alpha_for_torque(&tk, 2.0, &train_loads);
            close(a_m, a_t, a_m.abs().max(1.0), "alpha for torque");
            // Velocities: the rod's rate and the piston's speed.
            close(tk.cylinders[0].rod_rate_rad_s, k.qd[5], omega, "rod rate");
            close(
                tk.cylinders[0].piston_speed_m_s,
                k.qd[7],
                omega,
                "piston speed",
            );
        }
    }

    #[test]
    fn a_v_cylinder_is_the_inline_cylinder_turned_by_its_bank() {
        // One cylinder banked by beta, crank angle theta + beta, gravity off: the same
        // mechanism turned by beta, so every force is the inline one rotated.
        let rod = two_mass_rod(0.4, 0.12, 0.04);
        let make = |bank: f64| {
            CrankTrain::new(EngineGeometry {
                crank_radius_m: 0.03,
                crank_mass_kg: 2.0,
                crank_inertia_kg_m2: 0.003,
                drive_inertia_kg_m2: 0.0,
                gravity_m_s2: 0.0,
                mains_axial_m: vec![0.0, 0.1],
                throws: vec![throw(0.0, 0.05)],
                cylinders: vec![cylinder(0, bank, rod, 0.3)],
            })
            .expect("valid")
        };
        let (inline, v) = (make(0.0), make(72.0));
        let beta = 72.0_f64.to_radians();
        let loads = TrainLoads {
            main_torque_nm: -0.1,
            cylinders: vec![CylinderLoads {
                big_end_torque_nm: 0.03,
                small_end_torque_nm: -0.02,
                slide_force_n: 5.0,
            }],
        };
        for i in 0..36 {
            let theta = (10.0 * i as f64).to_radians();
            let a = inline.reactions(&inline.kinematics(theta, 500.0, &[300.0]), 40.0, &loads);
            let b = v.reactions(&v.kinematics(theta + beta, 500.0, &[300.0]), 40.0, &loads);
            let turn = Frame::new(beta);
            let expect = turn.to_global(a.cylinders[0].big_end_n);
            assert!((expect - b.cylinders[0].big_end_n).norm() < 1e-9 * expect.norm().max(1.0));
            let expect = turn.to_global(a.main_total_n);
            assert!((expect - b.main_total_n).norm() < 1e-9 * expect.norm().max(1.0));
            assert!(
                (a.cylinders[0].slide_lateral_n - b.cylinders[0].slide_lateral_n).abs()
                    < 1e-9 * 1e3
            );
            assert!(
                (a.drive_torque_nm - b.drive_torque_nm).abs()
                    < 1e-9 * (1.0 + a.drive_torque_nm.abs())
            );
        }
    }

    #[test]
    fn offset_piston_follows_its_line_and_the_train_conserves_energy() {
        // Pin and crank offsets: the small end stays on x = e, and without friction and gravity
        // the drive power equals the rate of change of kinetic energy (finite differences).
        let rod = RodGeometry {
            mass_kg: 0.5,
            inertia_kg_m2: 1.3e-3,
            length_m: 0.14,
            com_from_big_end_m: 0.05,
        };
        let mut c = cylinder(0, 0.0, rod, 0.45);
        c.pin_offset_m = 0.0015;
        c.crank_offset_m = 0.004;
        let train = CrankTrain::new(EngineGeometry {
            crank_radius_m: 0.04,
            crank_mass_kg: 4.0,
            crank_inertia_kg_m2: 0.005,
            drive_inertia_kg_m2: 0.0,
            gravity_m_s2: 0.0,
            mains_axial_m: vec![0.0, 0.1],
            throws: vec![throw(0.0, 0.05)],
            cylinders: vec![c],
        })
        .expect("valid");
        let energy = |theta: f64, omega: f64| {
            let k = &train.kinematics(theta, omega, &[]).cylinders[0];
            // Rod centre velocity from its position by a central difference in time.
            let h = 1e-6;
            let pos = |t: f64| train.kinematics(t, omega, &[]).cylinders[0].rod_com;
            let v = (pos(theta + omega * h) - pos(theta - omega * h)) / (2.0 * h);
            0.5 * train.crank_inertia_about_axis() * omega * omega
                + 0.5 * rod.mass_kg * v.norm_squared()
                + 0.5 * rod.inertia_kg_m2 * k.rod_rate_rad_s.powi(2)
                + 0.5 * 0.45 * k.piston_speed_m_s.powi(2)
        };
        for i in 0..24 {
            let theta = (15.0 * i as f64 + 1.0).to_radians();
            let k = train.kinematics(theta, 400.0, &[]);
            assert!((k.cylinders[0].small_end.x - 0.0055).abs() < 1e-15);
            let t = train.reactions(&k, 0.0, &frictionless(1)).drive_torque_nm;
            // dE/dt at constant speed = drive power.
            let dt = 1e-6;
            let de = (energy(theta + 400.0 * dt, 400.0) - energy(theta - 400.0 * dt, 400.0))
                / (2.0 * dt);
            assert!(
                (de - t * 400.0).abs() < 1e-4 * (1.0 + (t * 400.0).abs()),
                "{theta}: {de} vs {}",
                t * 400.0
            );
        }
    }

    #[test]
    fn firing_order_phases_and_misfits() {
        // Inline-4, throws 0-180-180-0, vertical: TDCs at 0, 180, 180, 0 degrees.
        let tdc: Vec<f64> = [0.0, -180.0, -180.0, 0.0]
            .iter()
            .map(|d: &f64| d.to_radians())
            .collect();
        let p = cylinder_phases(&tdc, &[1, 3, 4, 2], 0.0).expect("fits");
        // Cylinder 1 fires at 360, 3 at 540, 4 at 720, 2 at 900 (= 180): phases 0, 0, 2pi, 2pi.
        let deg: Vec<f64> = p.iter().map(|x| x.to_degrees().round()).collect();
        assert_eq!(deg, [0.0, 0.0, 360.0, 360.0]);
        // 1-2-3-4 on this crank: 2 and 3 share their TDCs, so 4 would fire with 1.
        let e = cylinder_phases(&tdc, &[1, 2, 3, 4], 0.0).expect_err("misfit");
        assert!(matches!(e, EngineError::OrderMisfit { .. }), "{e}");
        assert!(matches!(
            cylinder_phases(&tdc, &[1, 3, 3, 2], 0.0),
            Err(EngineError::NotPermutation { .. })
        ));
        assert!(matches!(
            cylinder_phases(&tdc, &[1, 3, 4], 0.0),
            Err(EngineError::NotPermutation { .. })
        ));
        // 90-degree V-twin on one throw, banks -45 and +45: TDCs at -45 and 45 degrees. 1
        // fires at 315; 2 at 405 (phase 0, 90 later) or 765 (phase 2 pi, 450 later): the more
        // even 450-270 is taken.
        let v: Vec<f64> = [-45.0_f64, 45.0].iter().map(|d| d.to_radians()).collect();
        let p = cylinder_phases(&v, &[1, 2], 0.0).expect("fits");
        assert_eq!(p[1].to_degrees().round(), 360.0);
        // A single cylinder keeps the rig's phase.
        assert_eq!(cylinder_phases(&[0.0], &[1], TAU).expect("one"), [TAU]);
    }
}
