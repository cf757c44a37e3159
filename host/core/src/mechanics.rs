//! Planar rigid multibody mechanics of the motored rig.
//!
//! Formulation: absolute coordinates. Each moving body `k` (crank, rod, piston) has the position
//! of its centre of mass and its angle, `q_k = (x, y, phi)`; joints are algebraic constraints
//! `Phi(q, t) = 0` (revolute: 2 equations, slide to ground: 2, crank driver: 1). The rig has 9
//! coordinates and 9 constraints including the driver, so kinematics is a square system and the
//! equations of motion
//!
//! ```text
//! M q'' + Phi_q^T lambda = Q          Phi_q q'' = gamma
//! ```
//!
//! give the accelerations from the constraints and the multipliers `lambda` (the joint reactions
//! and the driver torque) from `Phi_q^T lambda = Q - M q''` with the same LU factorisation. For a
//! free (torque-driven) crank the same solve is used twice: everything is affine in the crank's
//! angular acceleration, which is then chosen so the driver torque equals the applied torque.
//!
//! Frame: y along the cylinder axis pointing to the head, x across it, angles counter-clockwise.
//! The crank angle `theta` is measured from top dead centre: crank pin at `R(-sin theta, cos theta)`.

use nalgebra::{SMatrix, SVector, Vector2};

/// Number of generalised coordinates: three moving bodies, three each.
pub const NQ: usize = 9;
/// Constraint equations: main bearing 2, big end 2, small end 2, slide 2, driver 1.
pub const NC: usize = 9;

/// Coordinate vector.
pub type Q = SVector<f64, NQ>;
type Jac = SMatrix<f64, NC, NQ>;

/// Index of each moving body in the coordinate vector (body `b` owns `3b..3b+3`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Body {
    /// The crankshaft, rotating about the main-bearing axis at the origin.
    Crank = 0,
    /// The connecting rod.
    Rod = 1,
    /// The piston assembly (piston, rings, pin, clips).
    Piston = 2,
}

/// Mass properties and geometry of the rig, SI units.
#[derive(Debug, Clone, PartialEq)]
pub struct RigGeometry {
    /// Crank radius (half the stroke), m.
    pub crank_radius_m: f64,
    /// Rod length between pin centres, m.
    pub rod_length_m: f64,
    /// Rod centre of mass distance from the big-end centre, along the rod, m.
    pub rod_com_from_big_end_m: f64,
    /// Crank moment of inertia about its own centre of mass, kg m^2 (includes the balanced part).
    pub crank_inertia_kg_m2: f64,
    /// Crank mass, kg (all of it: balanced part plus unbalance).
    pub crank_mass_kg: f64,
    /// Crank centre-of-mass offset from the axis, m, and its angle from the crank pin
    /// direction (pi: a counterweight opposite the pin).
    pub crank_com_offset_m: f64,
    /// See `crank_com_offset_m`.
    pub crank_com_angle_rad: f64,
    /// Rod mass, kg.
    pub rod_mass_kg: f64,
    /// Rod in-plane moment of inertia about its centre of mass, kg m^2.
    pub rod_inertia_kg_m2: f64,
    /// Piston assembly mass, kg.
    pub piston_mass_kg: f64,
    /// Gravitational acceleration along -y, m/s^2 (0 for gravity off).
    pub gravity_m_s2: f64,
    /// Moment of inertia added to the crank by a drive (motor through a belt), kg m^2.
    pub drive_inertia_kg_m2: f64,
}

/// Kinematic state of all bodies.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct State {
    /// Positions and angles.
    pub q: Q,
    /// Velocities.
    pub qd: Q,
    /// Accelerations.
    pub qdd: Q,
}

/// Applied generalised forces from friction and damping laws, per joint.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct JointLoads {
    /// Torque on the crank from the main bearings (both together), N m.
    pub main_torque_nm: f64,
    /// Torque on the rod from the big end (the crank receives the opposite), N m.
    pub big_end_torque_nm: f64,
    /// Torque on the piston from the small end (the rod receives the opposite), N m.
    pub small_end_torque_nm: f64,
    /// Force on the piston along +y from the cylinder slide, N.
    pub slide_force_n: f64,
}

impl JointLoads {
    /// Linear extrapolation from `earlier` through `self` by `ratio` of the interval between
    /// them: a starting guess for the friction iteration at a nearby instant.
    pub fn extrapolated(&self, earlier: &JointLoads, ratio: f64) -> JointLoads {
        let (a, b) = (self.components(), earlier.components());
        JointLoads::from_components(std::array::from_fn(|i| a[i] + ratio * (a[i] - b[i])))
    }

    /// The four loads in the order of the multiplier responses: main, big end, small end, slide.
    fn components(&self) -> [f64; 4] {
        [
            self.main_torque_nm,
            self.big_end_torque_nm,
            self.small_end_torque_nm,
            self.slide_force_n,
        ]
    }

    fn from_components([main, big_end, small_end, slide]: [f64; 4]) -> JointLoads {
        JointLoads {
            main_torque_nm: main,
            big_end_torque_nm: big_end,
            small_end_torque_nm: small_end,
            slide_force_n: slide,
        }
    }
}

/// Joint reactions for one configuration: forces on the second body of each joint, N.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reactions {
    /// Force from the ground on the crank at the main bearings (sum of both), N.
    pub main_n: Vector2<f64>,
    /// Force from the crank on the rod at the big end, N.
    pub big_end_n: Vector2<f64>,
    /// Force from the rod on the piston at the small end, N.
    pub small_end_n: Vector2<f64>,
    /// Lateral force from the cylinder on the piston (x component), N.
    pub slide_lateral_n: f64,
    /// Moment from the cylinder on the piston, N m.
    pub slide_moment_nm: f64,
    /// Torque the drive applies to the crank (counter-clockwise, i.e. along theta), N m.
    pub drive_torque_nm: f64,
}

fn rot(phi: f64) -> (f64, f64) {
    (phi.cos(), phi.sin())
}

/// `A(phi) s` and `B(phi) s = dA/dphi s` for a local vector `s`, the rotation given as
/// `(cos phi, sin phi)`.
fn a_s((c, sn): (f64, f64), s: Vector2<f64>) -> (Vector2<f64>, Vector2<f64>) {
    let a = Vector2::new(c * s.x - sn * s.y, sn * s.x + c * s.y);
    (a, Vector2::new(-a.y, a.x))
}

/// The crank's and the rod's rotations `(cos, sin)` in one configuration.
#[derive(Debug, Clone, Copy)]
struct Rotations {
    crank: (f64, f64),
    rod: (f64, f64),
}

impl Rotations {
    /// The cosines and sines of the angles in the positions `q` (the general route).
    fn of(q: &Q) -> Self {
        Self {
            crank: rot(q[2]),
            rod: rot(q[5]),
        }
    }
}

/// The rig as a constrained multibody system: local attachment points and mass matrix.
#[derive(Debug, Clone)]
pub struct Mechanism {
    geo: RigGeometry,
    /// Main-bearing axis in the crank frame (relative to the crank CoM).
    crank_axis_local: Vector2<f64>,
    /// Crank pin in the crank frame.
    crank_pin_local: Vector2<f64>,
    /// Big end in the rod frame (rod axis along local +y, big end below the CoM).
    rod_big_local: Vector2<f64>,
    /// Small end in the rod frame.
    rod_small_local: Vector2<f64>,
    mass: Q,
}

impl Mechanism {
    /// Build from geometry; the caller has validated it (positive masses, rod longer than crank).
    pub fn new(geo: RigGeometry) -> Self {
        // Crank frame: origin at the crank CoM, pin direction along local +y, so the body angle
        // equals theta. The CoM sits at `offset` from the axis at `com_angle` from the pin.
        let (c, s) = rot(geo.crank_com_angle_rad);
        let com_from_axis = Vector2::new(-s, c) * geo.crank_com_offset_m;
        let crank_axis_local = -com_from_axis;
        let crank_pin_local = Vector2::new(0.0, geo.crank_radius_m) - com_from_axis;
        let rod_big_local = Vector2::new(0.0, -geo.rod_com_from_big_end_m);
        let rod_small_local = Vector2::new(0.0, geo.rod_length_m - geo.rod_com_from_big_end_m);
        let mut mass = Q::zeros();
        mass[0] = geo.crank_mass_kg;
        mass[1] = geo.crank_mass_kg;
        mass[2] = geo.crank_inertia_kg_m2 + geo.drive_inertia_kg_m2;
        mass[3] = geo.rod_mass_kg;
        mass[4] = geo.rod_mass_kg;
        mass[5] = geo.rod_inertia_kg_m2;
        mass[6] = geo.piston_mass_kg;
        mass[7] = geo.piston_mass_kg;
        // The piston does not rotate (the slide holds its angle); any positive value keeps
        // the mass matrix regular and never enters the result.
        mass[8] = 1.0;
        Self {
            geo,
            crank_axis_local,
            crank_pin_local,
            rod_big_local,
            rod_small_local,
            mass,
        }
    }

    /// The geometry this mechanism was built from.
    pub fn geometry(&self) -> &RigGeometry {
        &self.geo
    }

    /// Piston travel from top dead centre, m, in positions `q` (the piston pin's height
    /// below its TDC height `r + l`): what the laws are handed, read from the positions the
    /// solve has already computed.
    #[inline]
    pub fn piston_travel(&self, q: &Q) -> f64 {
        self.geo.crank_radius_m + self.geo.rod_length_m - q[3 * Body::Piston as usize + 1]
    }

    /// Exact positions for crank angle `theta` (closed form of the slider-crank).
    pub fn positions(&self, theta: f64) -> Q {
        self.pose(theta).0
    }

    /// [`Mechanism::positions`] with the crank's and the rod's rotations. The rod's cosine and
    /// sine are the closed form's own numbers, the components of its unit vector
    /// (`sin psi = -r sin(theta) / l`, `cos psi = sqrt(l^2 - r^2 sin^2(theta)) / l`), not a
    /// second `sin_cos` of the angle `atan2` makes of them (which the laws are handed).
    fn pose(&self, theta: f64) -> (Q, Rotations) {
        let r = self.geo.crank_radius_m;
        let l = self.geo.rod_length_m;
        let (sin, cos) = theta.sin_cos();
        let (a_axis, _) = a_s((cos, sin), self.crank_axis_local);
        let crank_com = -a_axis;
        let pin = Vector2::new(-r * sin, r * cos);
        let y_piston = r * cos + (l * l - (r * sin).powi(2)).sqrt();
        let small = Vector2::new(0.0, y_piston);
        let u = (small - pin) / l;
        // Rod angle: local +y maps onto u, so u = (-sin psi, cos psi), with cos psi > 0 (the rod
        // is longer than the crank throw): one division and an arctangent, cheaper than the
        // general two-argument form, to within an ulp of it.
        let psi = (-u.x / u.y).atan();
        let rod_com = pin + u * self.geo.rod_com_from_big_end_m;
        let rotations = Rotations {
            crank: (cos, sin),
            rod: (u.y, -u.x),
        };
        let q = Q::from_column_slice(&[
            crank_com.x,
            crank_com.y,
            theta,
            rod_com.x,
            rod_com.y,
            psi,
            0.0,
            y_piston,
            0.0,
        ]);
        (q, rotations)
    }

    /// Constraint Jacobian `Phi_q` (depends on positions only).
    fn jacobian_matrix(&self, q: &Q) -> Jac {
        let mut j = Jac::zeros();
        let Rotations { crank: pc, rod: pr } = Rotations::of(q);
        // Main bearing: r_c + A_c s_axis = 0.
        let (_, b) = a_s(pc, self.crank_axis_local);
        j[(0, 0)] = 1.0;
        j[(1, 1)] = 1.0;
        j[(0, 2)] = b.x;
        j[(1, 2)] = b.y;
        // Big end: r_c + A_c s_pin - r_r - A_r s_big = 0.
        let (_, bc) = a_s(pc, self.crank_pin_local);
        let (_, br) = a_s(pr, self.rod_big_local);
        j[(2, 0)] = 1.0;
        j[(3, 1)] = 1.0;
        j[(2, 2)] = bc.x;
        j[(3, 2)] = bc.y;
        j[(2, 3)] = -1.0;
        j[(3, 4)] = -1.0;
        j[(2, 5)] = -br.x;
        j[(3, 5)] = -br.y;
        // Small end: r_r + A_r s_small - r_p = 0 (piston pin at the piston CoM).
        let (_, br) = a_s(pr, self.rod_small_local);
        j[(4, 3)] = 1.0;
        j[(5, 4)] = 1.0;
        j[(4, 5)] = br.x;
        j[(5, 5)] = br.y;
        j[(4, 6)] = -1.0;
        j[(5, 7)] = -1.0;
        // Slide to ground along y: x_p = 0 and phi_p = 0.
        j[(6, 6)] = 1.0;
        j[(7, 8)] = 1.0;
        // Driver: phi_c - theta(t) = 0.
        j[(8, 2)] = 1.0;
        j
    }

    /// Acceleration right-hand side `gamma = -(Phi_q q')_q q'` without the driver's `theta''`,
    /// in the configuration with rotations `rotations`.
    fn gamma(&self, rotations: &Rotations, qd: &Q) -> SVector<f64, NC> {
        let mut g = SVector::<f64, NC>::zeros();
        let Rotations { crank: pc, rod: pr } = *rotations;
        let (wc, wr) = (qd[2], qd[5]);
        let (a, _) = a_s(pc, self.crank_axis_local);
        g[0] = a.x * wc * wc;
        g[1] = a.y * wc * wc;
        let (ac, _) = a_s(pc, self.crank_pin_local);
        let (ar, _) = a_s(pr, self.rod_big_local);
        g[2] = ac.x * wc * wc - ar.x * wr * wr;
        g[3] = ac.y * wc * wc - ar.y * wr * wr;
        let (ar, _) = a_s(pr, self.rod_small_local);
        g[4] = ar.x * wr * wr;
        g[5] = ar.y * wr * wr;
        g
    }

    /// Everything about the configuration at crank angle `theta` and speed `omega` that does
    /// not depend on the loads: positions, velocities, the accelerations as an affine function
    /// of the crank acceleration, and the multipliers' responses to the crank acceleration and
    /// to each friction load. Done once per evaluation; the friction/reaction iteration then
    /// only combines vectors.
    pub fn kinematics(&self, theta: f64, omega: f64) -> Kinematics {
        self.kinematics_with_piston_force(theta, omega, 0.0)
    }

    /// [`Mechanism::kinematics`] with a known force `piston_force_n` applied to the piston along
    /// +y (towards the head), such as the net gas force: it enters the multipliers' load-free
    /// part like gravity does.
    pub fn kinematics_with_piston_force(
        &self,
        theta: f64,
        omega: f64,
        piston_force_n: f64,
    ) -> Kinematics {
        let mut out = Kinematics::zeros();
        self.kinematics_into(theta, omega, piston_force_n, &mut out);
        out
    }

    /// [`Mechanism::kinematics_with_piston_force`] written into `out`: the solver's scratch,
    /// filled field by field once per evaluation instead of a whole configuration returned
    /// by value and copied in (720 bytes).
    #[inline]
    pub fn kinematics_into(
        &self,
        theta: f64,
        omega: f64,
        piston_force_n: f64,
        out: &mut Kinematics,
    ) {
        let (q, rotations) = self.pose(theta);
        let c = self.columns(&rotations);
        let mut e9 = Q::zeros();
        e9[8] = 1.0;
        // Velocities: Phi_q q' = (0, ..., omega).
        let qd = c.solve(&(e9 * omega));
        // Accelerations: Phi_q q'' = gamma(q, q') + alpha * e9.
        let qdd0 = c.solve(&self.gamma(&rotations, &qd));
        let qdd_alpha = c.solve(&e9);
        let parts = (q, qd, qdd0, qdd_alpha);
        self.multipliers(parts, piston_force_n, |rhs| c.solve_transpose(rhs), out);
    }

    /// [`Mechanism::kinematics`] by dense LU factorisation of the full constraint Jacobian: the
    /// general multibody route, kept as the reference the structured solve is tested against.
    pub fn kinematics_dense(&self, theta: f64, omega: f64) -> Kinematics {
        let q = self.positions(theta);
        let jac = self.jacobian_matrix(&q);
        let lu = jac.lu();
        let lu_t = jac.transpose().lu();
        let solve = |rhs: &Q| lu.solve(rhs).unwrap_or_else(Q::zeros);
        let mut e9 = Q::zeros();
        e9[8] = 1.0;
        let qd = solve(&(e9 * omega));
        let qdd0 = solve(&self.gamma(&Rotations::of(&q), &qd));
        let qdd_alpha = solve(&e9);
        let mut out = Kinematics::zeros();
        let parts = (q, qd, qdd0, qdd_alpha);
        self.multipliers(
            parts,
            0.0,
            |rhs| lu_t.solve(rhs).unwrap_or_else(Q::zeros),
            &mut out,
        );
        out
    }

    /// Multipliers' responses (gravity and inertia at alpha = 0, per unit alpha, per unit friction
    /// load) from `Phi_q^T lambda = Q - M q''`, given a solver for `Phi_q^T`; `piston_force_n`
    /// is an applied force on the piston along +y besides gravity. Written into `out` with the
    /// positions, velocities and accelerations `(q, qd, qdd0, qdd_alpha)`.
    #[inline]
    fn multipliers(
        &self,
        (q, qd, qdd0, qdd_alpha): (Q, Q, Q, Q),
        piston_force_n: f64,
        solve_t: impl Fn(&Q) -> Q,
        out: &mut Kinematics,
    ) {
        let gv = self.geo.gravity_m_s2;
        let mut gravity = Q::zeros();
        gravity[1] = -self.mass[0] * gv;
        gravity[4] = -self.mass[3] * gv;
        gravity[7] = -self.mass[6] * gv;
        // Only a rig with a gas load adds anything: the thesis rig's numbers stay bit for bit.
        if piston_force_n != 0.0 {
            gravity[7] += piston_force_n;
        }
        let unit = |entries: &[(usize, f64)]| {
            let mut f = Q::zeros();
            for (i, v) in entries {
                f[*i] = *v;
            }
            solve_t(&f)
        };
        out.lambda0 = solve_t(&(gravity - self.mass.component_mul(&qdd0)));
        out.lambda_alpha = solve_t(&(-self.mass.component_mul(&qdd_alpha)));
        // Generalised force patterns of each friction load (see JointLoads).
        out.lambda_loads[0] = unit(&[(2, 1.0)]);
        out.lambda_loads[1] = unit(&[(2, -1.0), (5, 1.0)]);
        out.lambda_loads[2] = unit(&[(5, -1.0), (8, 1.0)]);
        out.lambda_loads[3] = unit(&[(7, 1.0)]);
        out.q = q;
        out.qd = qd;
        out.qdd0 = qdd0;
        out.qdd_alpha = qdd_alpha;
    }

    /// The position-dependent entries of `Phi_q` (see `jacobian_matrix` for the layout) in the
    /// configuration with rotations `rotations`.
    fn columns(&self, rotations: &Rotations) -> Columns {
        let Rotations { crank: pc, rod: pr } = *rotations;
        Columns {
            b_axis: a_s(pc, self.crank_axis_local).1,
            b_pin: a_s(pc, self.crank_pin_local).1,
            b_big: a_s(pr, self.rod_big_local).1,
            b_small: a_s(pr, self.rod_small_local).1,
        }
    }

    /// Solve the dynamics at crank angle/speed/acceleration `theta, omega, alpha` with the given
    /// friction loads: positions, velocities, accelerations of every body, every joint
    /// reaction, and the drive torque needed.
    pub fn solve(
        &self,
        theta: f64,
        omega: f64,
        alpha: f64,
        loads: &JointLoads,
    ) -> (State, Reactions) {
        let k = self.kinematics(theta, omega);
        (k.state(alpha), k.reactions(alpha, loads))
    }

    /// Kinetic energy of all bodies (including the drive inertia), J.
    pub fn kinetic_energy(&self, qd: &Q) -> f64 {
        let mut e = 0.0;
        for i in 0..8 {
            e += 0.5 * self.mass[i] * qd[i] * qd[i];
        }
        e
    }

    /// Potential energy in gravity, J (zero level at y = 0).
    pub fn potential_energy(&self, q: &Q) -> f64 {
        self.geo.gravity_m_s2 * (self.mass[0] * q[1] + self.mass[3] * q[4] + self.mass[6] * q[7])
    }
}

/// The load-independent part of one configuration (see [`Mechanism::kinematics`]).
#[derive(Debug, Clone)]
pub struct Kinematics {
    /// Positions.
    pub q: Q,
    /// Velocities.
    pub qd: Q,
    qdd0: Q,
    qdd_alpha: Q,
    lambda0: SVector<f64, NC>,
    lambda_alpha: SVector<f64, NC>,
    lambda_loads: [SVector<f64, NC>; 4],
}

impl Kinematics {
    /// Every entry zero: a scratch to be filled by [`Mechanism::kinematics_into`].
    pub fn zeros() -> Self {
        let z = SVector::<f64, NC>::zeros();
        Self {
            q: Q::zeros(),
            qd: Q::zeros(),
            qdd0: Q::zeros(),
            qdd_alpha: Q::zeros(),
            lambda0: z,
            lambda_alpha: z,
            lambda_loads: [z; 4],
        }
    }

    /// Positions, velocities and accelerations at crank acceleration `alpha`.
    pub fn state(&self, alpha: f64) -> State {
        State {
            q: self.q,
            qd: self.qd,
            qdd: self.qdd0 + self.qdd_alpha * alpha,
        }
    }

    fn lambda(&self, alpha: f64, loads: &JointLoads) -> SVector<f64, NC> {
        let mut l = self.lambda0 + self.lambda_alpha * alpha;
        for (response, load) in self.lambda_loads.iter().zip(loads.components()) {
            l += response * load;
        }
        l
    }

    /// Joint reactions and the drive torque at crank acceleration `alpha` under `loads`.
    pub fn reactions(&self, alpha: f64, loads: &JointLoads) -> Reactions {
        let l = self.lambda(alpha, loads);
        // Constraint force on body k is -Phi_q_k^T lambda: read each joint's force on its second
        // body (rod for the big end, piston for the small end; crank for the main bearing).
        Reactions {
            main_n: -Vector2::new(l[0], l[1]),
            big_end_n: Vector2::new(l[2], l[3]),
            small_end_n: Vector2::new(l[4], l[5]),
            slide_lateral_n: -l[6],
            slide_moment_nm: -l[7],
            drive_torque_nm: -l[8],
        }
    }

    /// The crank acceleration at which the drive torque equals `torque` under `loads` (a crank
    /// driven by a torque rather than a prescribed motion).
    pub fn alpha_for_torque(&self, torque: f64, loads: &JointLoads) -> f64 {
        // Only the drive torque's multiplier is needed: one row, not the whole solve.
        let at_zero = -self
            .lambda_loads
            .iter()
            .zip(loads.components())
            .fold(self.lambda0[8], |sum, (response, load)| {
                sum + response[8] * load
            });
        // d(drive torque)/d(alpha) is the mechanism's effective inertia at this angle (> 0).
        let inertia = -self.lambda_alpha[8];
        (torque - at_zero) / inertia
    }
}

/// The non-constant entries of the constraint Jacobian. The rig is a chain (block, crank, rod,
/// piston, block), so `Phi_q x = r` and `Phi_q^T y = g` solve by substitution in a fixed order
/// with one division, by the rod's axial projection `-L cos(psi)`, which never vanishes while
/// the rod is longer than the crank.
struct Columns {
    b_axis: Vector2<f64>,
    b_pin: Vector2<f64>,
    b_big: Vector2<f64>,
    b_small: Vector2<f64>,
}

impl Columns {
    /// Solve `Phi_q x = r`.
    fn solve(&self, r: &Q) -> Q {
        let mut x = Q::zeros();
        x[2] = r[8];
        x[0] = r[0] - self.b_axis.x * x[2];
        x[1] = r[1] - self.b_axis.y * x[2];
        x[6] = r[6];
        x[8] = r[7];
        let d = self.b_small.x - self.b_big.x;
        x[5] = (r[2] - x[0] - self.b_pin.x * x[2] + r[4] + x[6]) / d;
        x[3] = r[4] + x[6] - self.b_small.x * x[5];
        x[4] = x[1] + self.b_pin.y * x[2] - self.b_big.y * x[5] - r[3];
        x[7] = x[4] + self.b_small.y * x[5] - r[5];
        x
    }

    /// Solve `Phi_q^T y = g`.
    fn solve_transpose(&self, g: &Q) -> Q {
        let mut y = Q::zeros();
        y[5] = -g[7];
        y[3] = y[5] - g[4];
        y[7] = g[8];
        let d = self.b_small.x - self.b_big.x;
        y[4] = (g[5] - self.b_big.x * g[3] + self.b_big.y * y[3] - self.b_small.y * y[5]) / d;
        y[2] = y[4] - g[3];
        y[6] = g[6] + y[4];
        y[0] = g[0] - y[2];
        y[1] = g[1] - y[3];
        y[8] = g[2]
            - self.b_axis.x * y[0]
            - self.b_axis.y * y[1]
            - self.b_pin.x * y[2]
            - self.b_pin.y * y[3];
        y
    }
}
