#!/usr/bin/env python3
"""An independent check of Tribo's steady drivetrain in Exudyn (a multibody code of its own).

The rig's slider-crank (crank, rod, piston as planar rigid bodies with revolute and prismatic
joints, gravity as the rig has it) hangs on the rig's torsional chain, reflected to crank speed:
the motor node turning at the plateau speed exactly, then 1-coordinate rotational masses joined
by coordinate spring-dampers, the last one acting on the crank's rotation coordinate. Friction is
Coulomb on the joint reactions (the `fedem-friction` law's model: mu |F| r at the revolute joints,
mu |F_lateral| at the piston) with the coefficients of the law set given, updated before each
step from the reactions of the step before.

What comes from where, so that Exudyn and Tribo cannot be fed different rigs:
- the slider-crank and the joints' radii and load shares: the rig file (and the file it extends);
- the friction coefficients: the law set file (only `fedem-friction` laws are accepted);
- the chain's inertias and stiffnesses at crank speed: `tribo modes RIG --json`;
- the chain's damping: the rig file's elements, reflected with the same factor as the stiffness
  (`tribo modes --json` does not print damping); `--damping NAME=VALUE` overrides an element's
  damping here and, through `--set drivetrain.elements=[...]`, in every Tribo command run.

Each plateau first runs the crank rigidly at the plateau speed for two cycles (its mean drive
torque is the check that both codes have the same friction, and the chain's starting twist), then
starts the chain at constant speed (every node turning at the plateau speed, each spring twisted
by that mean torque, the slider-crank at top dead centre with its consistent speeds) and
integrates `--settle` seconds; the figures are those of the last cycle and, for the drift, of
the cycle `--drift-gap` seconds before it. Peak-to-peak values take each extreme from the
parabola through the extreme sample and its neighbours. Prints one JSON object: per plateau
Exudyn's figures, Tribo's and their relative differences.

    target/pyenv/bin/python tests/peers/exudyn_testbed.py --tribo target/release/tribo
"""
import argparse
import contextlib
import json
import math
import os
import subprocess
import sys
import time
import tomllib

import numpy as np

with contextlib.redirect_stdout(sys.stderr):  # keep standard output pure JSON
    import exudyn as exu
from exudyn.itemInterface import (
    CoordinateSpringDamper,
    LoadForceVector,
    LoadMassProportional,
    LoadTorqueVector,
    MarkerBodyMass,
    MarkerBodyPosition,
    MarkerBodyRigid,
    MarkerNodeCoordinate,
    MarkerNodeRigid,
    Node1D,
    NodePointGround,
    NodeRigidBody2D,
    ObjectConnectorCoordinate,
    ObjectGround,
    ObjectJointPrismatic2D,
    ObjectJointRevolute2D,
    ObjectRigidBody2D,
    ObjectRotationalMass1D,
    SensorNode,
    SensorObject,
)

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
GRAVITY_M_S2 = 9.80665  # standard gravity, as the rig's `gravity = true` means
SPECTRAL_RADIUS = 0.9  # Exudyn's default; 1 (no numerical damping) fails on the constraints


# ------------------------------------------------------------------------------------------
# inputs


def load_rig(path):
    """The rig file merged over the file it `extends` (tables key by key, the rest replaced)."""
    with open(path, "rb") as f:
        rig = tomllib.load(f)
    base_name = rig.pop("extends", None)
    if base_name is None:
        return rig
    base = load_rig(os.path.join(os.path.dirname(path), base_name))

    def merge(b, c):
        for k, v in c.items():
            if isinstance(v, dict) and isinstance(b.get(k), dict):
                merge(b[k], v)
            else:
                b[k] = v

    merge(base, rig)
    return base


def toml_inline(value):
    """A value as inline TOML (strings, numbers, booleans, lists and tables of them)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return repr(float(value)) if isinstance(value, float) else str(value)
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, list):
        return "[" + ", ".join(toml_inline(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k} = {toml_inline(v)}" for k, v in value.items()) + "}"
    raise TypeError(f"no TOML form for {value!r}")


def chain_elements(rig, damping):
    """The rig's drivetrain elements with the damping overrides `{name: N m s/rad}` applied."""
    elements = [dict(e) for e in rig["drivetrain"]["elements"]]
    names = {e["name"] for e in elements if e["kind"] != "inertia"}
    for name, value in damping.items():
        if name not in names:
            sys.exit(f"--damping {name}: no compliant element of that name (have {sorted(names)})")
    for e in elements:
        if e["name"] in damping:
            e["damping_nm_s_per_rad"] = damping[e["name"]]
    return elements


def tribo_json(tribo, args):
    out = subprocess.run([tribo, "--quiet", *args, "--json"], capture_output=True, text=True)
    if out.returncode != 0:
        sys.exit(f"tribo {' '.join(args)} failed:\n{out.stderr}")
    return json.loads(out.stdout)


def reflected_chain(modes, elements):
    """Inertias (motor first, crank last), and per spring (k, c, ratio) at crank speed: the
    stiffness as `tribo modes` reflects it, the damping by the same factor, and the element's
    speed over the crank's (torque in the element = reflected torque / ratio)."""
    compliant = [e for e in elements if e["kind"] != "inertia"]
    springs = []
    for report, e in zip(modes["springs"], compliant, strict=True):
        if report["name"] != e["name"]:
            sys.exit(f"tribo modes lists spring {report['name']!r} where the rig has {e['name']!r}")
        factor = report["stiffness_nm_per_rad"] / e["stiffness_nm_per_rad"]  # ratio^2
        if e.get("backlash_rad", 0.0) != 0.0:
            sys.exit(f"{e['name']}: backlash is not modelled in this peer")
        springs.append(
            {
                "name": e["name"],
                "k": report["stiffness_nm_per_rad"],
                "c": e.get("damping_nm_s_per_rad", 0.0) * factor,
                "ratio": math.sqrt(factor),
                "transducer": e["kind"] == "transducer",
            }
        )
    inertias = [n["inertia_kg_m2"] for n in modes["inertias"]]
    if modes["motor_hold"] != "prescribed":
        sys.exit("this peer holds the motor at the plateau speed: the rig's drive must be prescribed")
    return inertias, springs


def coulomb_coefficients(lawset, rig):
    """Friction per joint from a law set of `fedem-friction` laws: mu and the joint's radius."""
    with open(lawset, "rb") as f:
        laws = tomllib.load(f)["laws"]
    mu = {}
    for law in laws:
        if law["law"] != "fedem-friction":
            sys.exit(f"{lawset}: law {law['law']!r} on {law['joint']!r}: this peer models fedem-friction only")
        params = law.get("params", {})
        if set(params) - {"mu"}:
            sys.exit(f"{lawset}: {law['joint']}: only `mu` is modelled (prestress, Stribeck: not)")
        joints = [j for j in rig["joints"] if j == law["joint"] or (law["joint"].endswith("*") and j.startswith(law["joint"][:-1]))]
        for j in joints:
            mu[j] = params.get("mu", 0.0025)
    joints = rig["joints"]
    mains = [j for j in joints if j.startswith("main")]
    # Each main bearing carries its load share of the crank's radial reaction.
    main_torque_per_n = sum(mu.get(j, 0.0) * joints[j]["radius_m"] * joints[j].get("load_share", 1.0) for j in mains)
    return {
        "main": main_torque_per_n,
        "big_end": mu.get("big_end", 0.0) * joints["big_end"]["radius_m"],
        "small_end": mu.get("small_end", 0.0) * joints["small_end"]["radius_m"],
        "piston": mu.get("piston", 0.0),
    }


# ------------------------------------------------------------------------------------------
# the Exudyn model


def simulate(rig, chain, mu, rpm, h_target, revs, static_torque=0.0):
    """`revs` revolutions at plateau speed `rpm` from constant speed: with `chain = (inertias,
    springs)` the crank hangs on the chain (the motor node turning at the plateau speed), else
    the crank itself turns at it (rigid). Returns the sample times, the torque (the
    transducer's, or the rigid drive's), the crank speed and the step."""
    g = rig["geometry"]
    b = rig["bodies"]
    R = g["crank_radius_m"]
    L = b["rod"]["length_m"]
    a = b["rod"]["com_from_big_end_m"]
    grav = GRAVITY_M_S2 if g.get("gravity", False) else 0.0
    if b["crank"].get("unbalance_mass_kg", 0.0) != 0.0 or g.get("pin_offset_m", 0.0) != 0.0:
        sys.exit("this peer models a balanced crank and no piston-pin offset")
    omega = rpm * math.pi / 30.0
    rev_s = 2.0 * math.pi / omega
    steps_per_rev = max(16, round(rev_s / h_target))
    h = rev_s / steps_per_rev

    SC = exu.SystemContainer()
    mbs = SC.AddSystem()
    ground = mbs.AddObject(ObjectGround())
    ground_node = mbs.AddNode(NodePointGround(referenceCoordinates=[0, 0, 0]))

    # Slider-crank at top dead centre, turning at omega: crank pin at (0, R), piston on +y.
    w_rod = -omega * R / L  # the rod's angular speed at TDC (small end at rest)
    crank_node = mbs.AddNode(NodeRigidBody2D(referenceCoordinates=[0, 0, 0], initialVelocities=[0, 0, omega]))
    crank = mbs.AddObject(ObjectRigidBody2D(nodeNumber=crank_node, mass=b["crank"]["mass_kg"], inertia=b["crank"]["inertia_kg_m2"]))
    rod_node = mbs.AddNode(
        NodeRigidBody2D(referenceCoordinates=[0, R + a, 0.5 * math.pi], initialVelocities=[-omega * R - w_rod * a, 0, w_rod])
    )
    rod = mbs.AddObject(ObjectRigidBody2D(nodeNumber=rod_node, mass=b["rod"]["mass_kg"], inertia=b["rod"]["inertia_kg_m2"]))
    piston_node = mbs.AddNode(NodeRigidBody2D(referenceCoordinates=[0, R + L, 0]))
    # The piston's rotation is locked by its slide: its inertia is a placeholder.
    piston = mbs.AddObject(ObjectRigidBody2D(nodeNumber=piston_node, mass=b["piston"]["mass_kg"], inertia=1e-4))

    m_ground = mbs.AddMarker(MarkerBodyPosition(bodyNumber=ground, localPosition=[0, 0, 0]))
    m_slide = mbs.AddMarker(MarkerBodyRigid(bodyNumber=ground, localPosition=[0, R + L, 0]))
    m_axis = mbs.AddMarker(MarkerBodyPosition(bodyNumber=crank, localPosition=[0, 0, 0]))
    m_pin = mbs.AddMarker(MarkerBodyPosition(bodyNumber=crank, localPosition=[0, R, 0]))
    m_big = mbs.AddMarker(MarkerBodyPosition(bodyNumber=rod, localPosition=[-a, 0, 0]))
    m_small = mbs.AddMarker(MarkerBodyPosition(bodyNumber=rod, localPosition=[L - a, 0, 0]))
    m_piston = mbs.AddMarker(MarkerBodyPosition(bodyNumber=piston, localPosition=[0, 0, 0]))
    m_piston_rigid = mbs.AddMarker(MarkerBodyRigid(bodyNumber=piston, localPosition=[0, 0, 0]))
    main_joint = mbs.AddObject(ObjectJointRevolute2D(markerNumbers=[m_ground, m_axis]))
    big_joint = mbs.AddObject(ObjectJointRevolute2D(markerNumbers=[m_pin, m_big]))
    mbs.AddObject(ObjectJointRevolute2D(markerNumbers=[m_small, m_piston]))
    slide = mbs.AddObject(
        ObjectJointPrismatic2D(
            markerNumbers=[m_slide, m_piston_rigid], axisMarker0=[0, 1, 0], normalMarker1=[1, 0, 0], constrainRotation=True
        )
    )
    if grav > 0.0:
        for body in (crank, rod, piston):
            mb = mbs.AddMarker(MarkerBodyMass(bodyNumber=body))
            mbs.AddLoad(LoadMassProportional(markerNumber=mb, loadVector=[0, -grav, 0]))
    crank_coord = mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=crank_node, coordinate=2))
    ground_coord = mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=ground_node, coordinate=0))

    def hold_speed(coord):
        # The speed imposed exactly (a velocity-level constraint: no user function per step).
        return mbs.AddObject(ObjectConnectorCoordinate(markerNumbers=[ground_coord, coord], offset=omega, velocityLevel=True))

    def record(node, kind):
        return mbs.AddSensor(SensorNode(nodeNumber=node, outputVariableType=kind, storeInternal=True, writeToFile=False))

    COORD, SPEED = exu.OutputVariableType.Coordinates, exu.OutputVariableType.Coordinates_t
    if chain is None:
        drive = hold_speed(crank_coord)
        drive_sensor = mbs.AddSensor(SensorObject(objectNumber=drive, outputVariableType=exu.OutputVariableType.Force, storeInternal=True, writeToFile=False))
    else:
        # The chain: the motor (its speed held), free rotational masses, the crank's rotation
        # coordinate; every node at the plateau speed, each spring twisted by `static_torque`.
        inertias, springs = chain
        angles = [0.0] * len(inertias)
        for i in reversed(range(len(springs))):
            angles[i] = angles[i + 1] + static_torque / springs[i]["k"]
        coords, nodes = [], []
        for i in range(len(inertias) - 1):
            n = mbs.AddNode(Node1D(referenceCoordinates=[0], initialCoordinates=[angles[i]], initialVelocities=[omega]))
            mbs.AddObject(ObjectRotationalMass1D(nodeNumber=n, inertia=inertias[i]))
            coords.append(mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=n, coordinate=0)))
            nodes.append(n)
        coords.append(crank_coord)
        for i, s in enumerate(springs):
            # Exudyn's force acts against q1 - q0: node i drives node i + 1 through it.
            mbs.AddObject(CoordinateSpringDamper(markerNumbers=[coords[i], coords[i + 1]], stiffness=s["k"], damping=s["c"]))
        hold_speed(coords[0])
        k = next(i for i, s in enumerate(springs) if s["transducer"])
        ends = [(record(n, COORD), record(n, SPEED)) for n in nodes[k : k + 2]]
    crank_speed_sensor = record(crank_node, SPEED)
    crank_angle_sensor = record(crank_node, COORD)

    # Coulomb friction on the reactions, as loads written before each step.
    crank_torque = mbs.AddLoad(LoadTorqueVector(markerNumber=mbs.AddMarker(MarkerNodeRigid(nodeNumber=crank_node)), loadVector=[0, 0, 0]))
    rod_torque = mbs.AddLoad(LoadTorqueVector(markerNumber=mbs.AddMarker(MarkerNodeRigid(nodeNumber=rod_node)), loadVector=[0, 0, 0]))
    piston_force = mbs.AddLoad(LoadForceVector(markerNumber=m_piston, loadVector=[0, 0, 0]))
    mbs.Assemble()

    i_crank = mbs.GetNodeODE2Index(crank_node)
    i_rod = mbs.GetNodeODE2Index(rod_node)
    i_piston = mbs.GetNodeODE2Index(piston_node)
    FORCE = exu.OutputVariableType.Force
    FORCE_LOCAL = exu.OutputVariableType.ForceLocal
    eps = 1e-3  # the law's smoothed sign at the piston: v / sqrt(v^2 + eps^2), eps in m/s

    def pre_step(mbs, t):
        f_main = mbs.GetObjectOutput(main_joint, FORCE)
        f_big = mbs.GetObjectOutput(big_joint, FORCE)
        f_slide = mbs.GetObjectOutput(slide, FORCE_LOCAL)  # lateral reaction in [0]
        v = mbs.systemData.GetODE2Coordinates_t()
        w_c, w_r, v_p = float(v[i_crank + 2]), float(v[i_rod + 2]), float(v[i_piston + 1])
        # The bearings never stop turning (their sliding speeds are metres per second against
        # the sign's 1 mm/s): a plain sign there.
        t_main = -mu["main"] * math.hypot(f_main[0], f_main[1]) * math.copysign(1.0, w_c)
        t_big = -mu["big_end"] * math.hypot(f_big[0], f_big[1]) * math.copysign(1.0, w_c - w_r)
        f_pis = -mu["piston"] * abs(f_slide[0]) * v_p / math.sqrt(v_p * v_p + eps * eps)
        mbs.SetLoadParameter(crank_torque, "loadVector", [0, 0, t_main + t_big])
        mbs.SetLoadParameter(rod_torque, "loadVector", [0, 0, -t_big])
        mbs.SetLoadParameter(piston_force, "loadVector", [0, f_pis, 0])
        return True

    mbs.SetPreStepUserFunction(pre_step)

    n_steps = revs * steps_per_rev
    ss = exu.SimulationSettings()
    ss.timeIntegration.numberOfSteps = n_steps
    ss.timeIntegration.endTime = n_steps * h
    ss.timeIntegration.verboseMode = 0
    ss.timeIntegration.generalizedAlpha.spectralRadius = SPECTRAL_RADIUS
    ss.timeIntegration.newton.useModifiedNewton = True
    ss.timeIntegration.newton.modifiedNewtonJacUpdatePerStep = True
    ss.solution.file.write = False
    ss.solution.sensors.writePeriod = h
    ss.solution.sensors.active = True
    ss.solution.solverInformationFileName = ""
    ss.show.statistics = False
    ss.show.computationTime = False
    with contextlib.redirect_stdout(sys.stderr):
        ok = mbs.SolveDynamic(ss, solverType=exu.DynamicSolverType.GeneralizedAlpha)
    if not ok:
        sys.exit(f"Exudyn did not solve the {rpm:.0f} rpm plateau")

    data = mbs.GetSensorStoredData(crank_speed_sensor)
    t, crank_speed = data[:, 0], data[:, 3]
    if chain is None:
        # Exudyn's multiplier is the constraint's reaction on the crank with a minus sign.
        torque = -mbs.GetSensorStoredData(drive_sensor)[:, 1]
    else:
        phi = [mbs.GetSensorStoredData(c)[:, 1] for c, _ in ends]
        w = [mbs.GetSensorStoredData(v)[:, 1] for _, v in ends]
        if len(ends) == 1:  # the transducer's crank-side end is the crank itself
            phi.append(mbs.GetSensorStoredData(crank_angle_sensor)[:, 3])
            w.append(crank_speed)
        s = springs[k]
        torque = (s["k"] * (phi[0] - phi[1]) + s["c"] * (w[0] - w[1])) / s["ratio"]
    return t, torque, crank_speed, steps_per_rev


def figures(torque, crank_speed, end, samples):
    """The figures of the `samples` samples before index `end`: one whole cycle."""
    tq, sp = torque[end - samples : end], crank_speed[end - samples : end]
    return {
        "transducer_mean_torque_nm": float(np.mean(tq)),
        "transducer_peak_to_peak_nm": float(peak(tq, +1) - peak(tq, -1)),
        "crank_speed_fluctuation": float((peak(sp, +1) - peak(sp, -1)) / np.mean(sp)),
    }


def plateau(rig, chain, mu, rpm, args, cycle_revs):
    """One plateau in Exudyn: the rigid crank's mean torque (a short run, for the chain's
    starting twist), then the crank on the chain for `--settle` seconds; the last cycle's
    figures and their drift since the cycle `--drift-gap` seconds before."""
    rev_s = 60.0 / rpm
    t0 = time.perf_counter()
    _, rigid_torque, rigid_speed, n = simulate(rig, None, mu, rpm, args.h, 2 * cycle_revs)
    rigid = figures(rigid_torque, rigid_speed, len(rigid_torque) - 1, cycle_revs * n)["transducer_mean_torque_nm"]
    gap = max(1, round(args.drift_gap / rev_s / cycle_revs)) * cycle_revs
    revs = max(gap + cycle_revs, math.ceil(args.settle / rev_s / cycle_revs) * cycle_revs)
    t, torque, speed, n = simulate(rig, chain, mu, rpm, args.h, revs, static_torque=rigid)
    last = len(t) - 1  # sample 0 is the start; a cycle of samples ends at the last one
    now = figures(torque, speed, last, cycle_revs * n)
    before = figures(torque, speed, last - gap * n, cycle_revs * n)
    return {
        "rigid_mean_torque_nm": rigid,
        "h_s": rev_s / n,
        "simulated_s": revs * rev_s,
        "wall_s": time.perf_counter() - t0,
        **now,
        "drift_gap_s": gap * rev_s,
        "drift": {key: abs(now[key] - before[key]) / abs(now[key]) for key in now},
    }


def peak(x, sign):
    """The periodic samples' maximum (`sign` +1) or minimum (-1), refined by the parabola
    through the extreme sample and its neighbours (the signal between samples)."""
    y = sign * np.asarray(x)
    i = int(np.argmax(y))
    a, b, c = y[i - 1], y[i], y[(i + 1) % len(y)]
    den = a - 2.0 * b + c
    top = b - 0.125 * (c - a) ** 2 / den if den < 0.0 else b
    return sign * top


# ------------------------------------------------------------------------------------------


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--tribo", default=os.path.join(ROOT, "target", "release", "tribo"))
    ap.add_argument("--rig", default=os.path.join(ROOT, "rigs", "crf250r-testbed.toml"))
    ap.add_argument("--lawset", default=os.path.join(HERE, "fedem-coulomb.toml"))
    ap.add_argument("--rpm", type=float, nargs="+", default=[3000.0, 6000.0, 9000.0])
    ap.add_argument("--damping", action="append", default=[], metavar="ELEMENT=N_M_S_PER_RAD",
                    help="an element's damping for this check (here and in Tribo), e.g. belt=0.05")
    ap.add_argument("--h", type=float, default=2e-5, help="Exudyn's step, s (rounded to whole steps per revolution)")
    ap.add_argument("--settle", type=float, default=8.0, help="simulated time per plateau, s")
    ap.add_argument("--drift-gap", type=float, default=0.5, help="time between the two cycles compared for drift, s")
    args = ap.parse_args()

    rig = load_rig(args.rig)
    damping = {}
    for item in args.damping:
        name, _, value = item.rpartition("=")
        damping[name] = float(value)
    elements = chain_elements(rig, damping)
    sets = ["--set", "drivetrain.elements=" + toml_inline(elements)]
    modes = tribo_json(args.tribo, ["modes", args.rig, *sets])
    inertias, springs = reflected_chain(modes, elements)
    mu = coulomb_coefficients(args.lawset, rig)

    steady = tribo_json(args.tribo, ["run", args.rig, "--lawset", args.lawset, "--steady", *sets])
    # The same slider-crank driven rigidly: the rig the test bed extends (it adds only the chain).
    with open(args.rig, "rb") as f:
        extends = tomllib.load(f).get("extends")
    if extends is None:
        sys.exit(f"{args.rig} extends no rig: the rigid check needs the slider-crank without the chain")
    base = os.path.join(os.path.dirname(args.rig), extends)
    rigid_run = tribo_json(args.tribo, ["run", base, "--lawset", args.lawset, "--steady"])
    rigid = {p["set_speed_rpm"]: p["motoring_torque_nm"] for p in rigid_run["plateaus"]}
    cycle_revs = 2 if rig["geometry"].get("engine_cycle") == "four-stroke" else 1
    plateaus = {p["set_speed_rpm"]: p for p in steady["plateaus"]}
    out = {"exudyn_version": exu.__version__, "damping_nm_s_per_rad": damping, "chain": {"inertias_kg_m2": inertias, "springs": springs}, "plateaus": []}
    for rpm in args.rpm:
        if rpm not in plateaus:
            sys.exit(f"the rig has no plateau at {rpm} rpm (has {sorted(plateaus)})")
        inst = plateaus[rpm]["instrument"]
        exu_fig = plateau(rig, (inertias, springs), mu, rpm, args, cycle_revs)
        tribo_fig = {
            "rigid_mean_torque_nm": rigid[rpm],
            "transducer_mean_torque_nm": inst["mean_torque_nm"],
            "transducer_peak_to_peak_nm": inst["peak_to_peak_nm"],
            "crank_speed_fluctuation": inst["crank_speed_fluctuation"],
            "settling_cycles": inst["settling_cycles"],
        }
        keys = ("rigid_mean_torque_nm", "transducer_mean_torque_nm", "transducer_peak_to_peak_nm", "crank_speed_fluctuation")
        rel = {k: (tribo_fig[k] - exu_fig[k]) / abs(exu_fig[k]) for k in keys}
        out["plateaus"].append({"rpm": rpm, "exudyn": exu_fig, "tribo": tribo_fig, "relative_difference": rel})
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
