//! The multibody mechanics against the thesis's closed forms (chapter 4), each reference
//! written out here from the equations, not from the solver.

use std::f64::consts::PI;

use tribo::mechanics::{JointLoads, Mechanism, RigGeometry};

const R: f64 = 0.0269; // crank radius, m (53.8 mm stroke)
const L: f64 = 0.105; // rod length, m
const M_ROD: f64 = 0.1748; // kg, thesis table 9.3
const M_PISTON: f64 = 0.27; // kg

fn rig(two_point_rod: bool) -> Mechanism {
    let (com, inertia) = if two_point_rod {
        // All rod mass at the pin centres, 2/3 at the big end: CoM at L/3, I = (2/9) m L^2.
        (L / 3.0, 2.0 / 9.0 * M_ROD * L * L)
    } else {
        (L / 3.0, 261.8e-6)
    };
    Mechanism::new(RigGeometry {
        crank_radius_m: R,
        rod_length_m: L,
        rod_com_from_big_end_m: com,
        crank_inertia_kg_m2: 0.004,
        crank_mass_kg: 3.0,
        crank_com_offset_m: 0.0,
        crank_com_angle_rad: PI,
        rod_mass_kg: M_ROD,
        rod_inertia_kg_m2: inertia,
        piston_mass_kg: M_PISTON,
        gravity_m_s2: 0.0,
        drive_inertia_kg_m2: 0.0,
    })
}

fn close(a: f64, b: f64, scale: f64, rel: f64) -> bool {
    (a - b).abs() <= rel * scale
}

#[test]
fn kinematics_match_thesis_equations_4_3_to_4_8() {
    let m = rig(false);
    let lam = R / L;
    for &omega in &[314.159, 942.478] {
        for k in 0..720 {
            let th = 2.0 * PI * k as f64 / 720.0;
            let (s, c) = th.sin_cos();
            let root = (1.0 - lam * lam * s * s).sqrt();
            // eq 4.3-4.5: displacement from TDC, velocity, acceleration.
            let disp = -R * (1.0 - c + (1.0 - root) / lam);
            let vel = -R * omega * (s + lam / 2.0 * (2.0 * th).sin() / root);
            let acc = -R
                * omega
                * omega
                * (c + (lam * (2.0 * th).cos() + lam.powi(3) * s.powi(4)) / root.powi(3));
            // eq 4.7-4.8: rod angle and rate (thesis sign: positive while the pin is on +x of
            // its own drawing; ours is counter-clockwise, the mirror image, hence the minus).
            let phi = (R * s / L).asin();
            let phid = omega * R / (1.0 - (R * R / (L * L)) * s * s).sqrt() * c / L;

            let (st, _) = m.solve(th, omega, 0.0, &JointLoads::default());
            let tol = 1e-9;
            assert!(close(st.q[7] - (R + L), disp, R, tol), "S at {th}");
            assert!(
                close(st.qd[7], vel, R * omega, tol),
                "S' at {th}: {} vs {vel}",
                st.qd[7]
            );
            assert!(close(st.qdd[7], acc, R * omega * omega, tol), "S'' at {th}");
            assert!(close(-st.q[5], phi, lam, tol), "phi at {th}");
            assert!(close(-st.qd[5], phid, lam * omega, tol), "phi' at {th}");
            assert_eq!(st.qd[2], omega);
        }
    }
}

#[test]
fn two_point_rod_loads_match_thesis_equations_4_9_to_4_13() {
    let m = rig(true);
    let lam = R / L;
    for &omega in &[314.159, 628.319, 942.478] {
        let scale = (M_PISTON + M_ROD) * R * omega * omega * 2.0;
        for k in 0..360 {
            let th = 2.0 * PI * k as f64 / 360.0 + 0.01;
            let (s, c) = th.sin_cos();
            let root = (1.0 - lam * lam * s * s).sqrt();
            let a_a = -R
                * omega
                * omega
                * (c + (lam * (2.0 * th).cos() + lam.powi(3) * s.powi(4)) / root.powi(3)); // 4.9
            let f_rec = (M_PISTON + M_ROD / 3.0) * a_a; // 4.10
            let f_rot = 2.0 / 3.0 * M_ROD * R * omega * omega; // 4.11
            let psi = (R * s / L).asin();
            let f_t = f_rec * psi.tan(); // 4.13 without gas force
                                         // Side thrust: the wall pushes the reciprocating mass against the rod's lateral
                                         // component; in this frame the pin is at -x for 0 < theta < pi, the rod leans to
                                         // +x at the piston, so the wall force on the piston is -F_T along x.
            let (_, re) = m.solve(th, omega, 0.0, &JointLoads::default());
            assert!(
                close(re.slide_lateral_n, -f_t, scale, 1e-9),
                "thrust at {th}: {} vs {}",
                re.slide_lateral_n,
                -f_t
            );
            // Big end: F_B = F_rec (along the axis) + F_T (across) + F_rot (towards the crank
            // centre, the force that makes the big-end mass go round), thesis section 4.3.
            let radial_in = [s, -c]; // unit vector from the pin to the crank centre
            let fb_x = f_t + f_rot * radial_in[0];
            let fb_y = f_rec + f_rot * radial_in[1];
            assert!(
                close(re.big_end_n.x, fb_x, scale, 1e-9),
                "big end x at {th}"
            );
            assert!(
                close(re.big_end_n.y, fb_y, scale, 1e-9),
                "big end y at {th}"
            );
            // A balanced crank at constant speed passes the big-end load straight to the mains.
            assert!(close(re.main_n.x, re.big_end_n.x, scale, 1e-9));
            assert!(close(re.main_n.y, re.big_end_n.y, scale, 1e-9));
        }
    }
}

#[test]
fn drive_torque_is_the_rate_of_kinetic_energy() {
    // At constant speed the frictionless drive torque times omega is dE/dt; check against a
    // central difference of the kinetic energy along the crank angle.
    let m = rig(false);
    let omega = 700.0;
    for k in 0..36 {
        let th = 2.0 * PI * k as f64 / 36.0 + 0.1;
        let h = 1e-5;
        let e = |t: f64| {
            let (st, _) = m.solve(t, omega, 0.0, &JointLoads::default());
            m.kinetic_energy(&st.qd)
        };
        let de_dtheta = (e(th + h) - e(th - h)) / (2.0 * h);
        let (_, re) = m.solve(th, omega, 0.0, &JointLoads::default());
        assert!(
            close(re.drive_torque_nm, de_dtheta, 100.0, 1e-6),
            "{th}: {} vs {de_dtheta}",
            re.drive_torque_nm
        );
    }
}

#[test]
fn structured_solve_equals_the_dense_lu_of_the_full_constraint_jacobian() {
    // An unbalanced crank and gravity, so every entry of the Jacobian and every load path is
    // exercised; the production path (substitution along the chain) must match the general
    // dense LU route to rounding.
    let m = Mechanism::new(RigGeometry {
        crank_radius_m: R,
        rod_length_m: L,
        rod_com_from_big_end_m: 0.031,
        crank_inertia_kg_m2: 0.004,
        crank_mass_kg: 3.2,
        crank_com_offset_m: 0.004,
        crank_com_angle_rad: 2.9,
        rod_mass_kg: M_ROD,
        rod_inertia_kg_m2: 261.8e-6,
        piston_mass_kg: M_PISTON,
        gravity_m_s2: 9.80665,
        drive_inertia_kg_m2: 0.001,
    });
    let loads = JointLoads {
        main_torque_nm: -0.31,
        big_end_torque_nm: 0.12,
        small_end_torque_nm: -0.05,
        slide_force_n: 21.0,
    };
    for k in 0..400 {
        let th = 2.0 * PI * k as f64 / 400.0 + 0.003;
        for (w, a) in [(0.0, 0.0), (314.0, 200.0), (942.5, -1500.0)] {
            let (fast, dense) = (m.kinematics(th, w), m.kinematics_dense(th, w));
            let (sf, sd) = (fast.state(a), dense.state(a));
            let (rf, rd) = (fast.reactions(a, &loads), dense.reactions(a, &loads));
            let scale = 1.0 + w * w;
            for i in 0..9 {
                assert!(
                    (sf.qd[i] - sd.qd[i]).abs() <= 1e-12 * (1.0 + w),
                    "qd[{i}] at {th}"
                );
                assert!(
                    (sf.qdd[i] - sd.qdd[i]).abs() <= 1e-11 * scale,
                    "qdd[{i}] at {th}"
                );
            }
            let pairs = [
                (rf.main_n.x, rd.main_n.x),
                (rf.main_n.y, rd.main_n.y),
                (rf.big_end_n.x, rd.big_end_n.x),
                (rf.big_end_n.y, rd.big_end_n.y),
                (rf.small_end_n.x, rd.small_end_n.x),
                (rf.small_end_n.y, rd.small_end_n.y),
                (rf.slide_lateral_n, rd.slide_lateral_n),
                (rf.slide_moment_nm, rd.slide_moment_nm),
                (rf.drive_torque_nm, rd.drive_torque_nm),
            ];
            for (i, (x, y)) in pairs.iter().enumerate() {
                assert!(
                    (x - y).abs() <= 1e-9 * scale,
                    "reaction {i} at theta {th}, omega {w}: {x} vs {y}"
                );
            }
            assert!(
                (fast.alpha_for_torque(3.0, &loads) - dense.alpha_for_torque(3.0, &loads)).abs()
                    <= 1e-9 * (1.0 + a.abs())
            );
        }
    }
}
