#!/usr/bin/env python3
"""Writes crf250r-fired-synthetic.csv: a SYNTHETIC fired pressure trace for the CRF 250 R rig
(not a measurement). Single-zone closed cycle with a Wiebe heat release:

    dp/dphi = (g - 1) / V * dQ/dphi - g * p / V * dV/dphi,   Q = Q_tot * x_b(phi)
    x_b = 1 - exp(-a ((phi - phi_0) / dphi)^(m + 1))

4-stroke angle phi in degrees, 0 = gas-exchange TDC, 360 = firing TDC. Intake (0-180) and
exhaust (540-720) at the intake pressure; the valves are ideal (closing and opening at the
dead centres, blowdown instantaneous at 540). Every number and its source:

- bore 76.8 mm [T 8.1], crank radius 26.9 mm [S: 2010-2017 spec sheets], rod 105 mm (estimate,
  as in crf250r-motored.toml)
- compression ratio 12.9 [S: public spec sheet of the 2004-2009 CRF250R]
- g = 1.3: estimate, a usual single-zone ratio of specific heats for burnt/unburnt mixture
- p_in = 101325 Pa: estimate, wide-open throttle without ram effect
- Q_tot = 700 J: estimate, trapped air rho V_bdc eta_v = 1.18 kg/m3 * 272 cm3 * 0.9, AFR 13,
  fuel LHV 44 MJ/kg, combustion efficiency 0.95 -> ~880 J, reduced for heat loss to ~700 J
- Wiebe a = 5, m = 2, start 345 deg (15 deg before firing TDC), duration 50 deg: estimates,
  textbook values for a spark-ignition engine
"""
import math

BORE, R, L = 0.0768, 0.0269, 0.105
CR, G, P_IN, Q_TOT = 12.9, 1.3, 101325.0, 700.0
A_W, M_W, PHI0, DPHI = 5.0, 2.0, 345.0, 50.0
AREA = math.pi / 4 * BORE ** 2
VD = AREA * 2 * R
VC = VD / (CR - 1)


def volume(phi_deg):
    th = math.radians(phi_deg)
    s = R * math.sin(th)
    x = R + L - R * math.cos(th) - math.sqrt(L * L - s * s)
    return VC + AREA * x


def burned(phi):
    if phi <= PHI0:
        return 0.0
    return 1.0 - math.exp(-A_W * ((phi - PHI0) / DPHI) ** (M_W + 1))


def rate(phi, p):
    h = 1e-4
    dv = (volume(phi + h) - volume(phi - h)) / (2 * h)
    dq = Q_TOT * (burned(phi + h) - burned(phi - h)) / (2 * h)
    v = volume(phi)
    return (G - 1) / v * dq - G * p / v * dv


def main():
    rows = []
    p = P_IN
    phi = 180.0
    step = 0.01
    closed = {}
    while phi < 540.0 - 1e-9:
        if abs(phi - round(phi)) < 1e-6:
            closed[int(round(phi))] = p
        k1 = rate(phi, p)
        k2 = rate(phi + step / 2, p + step / 2 * k1)
        k3 = rate(phi + step / 2, p + step / 2 * k2)
        k4 = rate(phi + step, p + step * k3)
        p += step / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        phi += step
    closed[540] = p
    for d in range(0, 720):
        if 180 <= d <= 540:
            rows.append((float(d), closed[d]))
        else:
            rows.append((float(d), P_IN))
        if d == 540:
            rows.append((540.5, P_IN))  # blowdown at the ideal exhaust opening
    with open("crf250r-fired-synthetic.csv", "w") as f:
        f.write("# SYNTHETIC fired cycle (Wiebe heat release on a polytropic single-zone cycle),\n")
        f.write("# NOT a measurement: see crf250r-fired-synthetic.py for every number's source.\n")
        f.write("crank_angle_deg,pressure_pa\n")
        for a, pr in rows:
            f.write(f"{a:g},{pr:.1f}\n")


if __name__ == "__main__":
    main()
