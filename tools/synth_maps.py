#!/usr/bin/env python3
"""Synthesize the *assumed* lookup tables of the SimRod twin.

The thesis shows its maps only as figures (5.7, 5.10-5.15, 5.24-5.25, 5.42-5.47);
their numbers are not published. This script writes tables that reproduce the shapes
and limits the thesis states (MODEL.md), and that are consistent with the steady state
of the twin's own mechanics, so that maps and dynamics do not contradict each other.

Every constant here is an assumption; each is named next to its use and repeated in
model-core/data/parameters.toml or the header of the file it produces. A user with a
real bench replaces the generated CSV files with identified ones (`simrod identify`)
and rebuilds; this script is then no longer involved.

Run from the repository root:  python3 tools/synth_maps.py
"""
import math
import os

OUT = os.path.join(os.path.dirname(__file__), "..", "model-core", "data")

GEAR = 2100.0 / 190.0            # SuT gearbox ratio, tables 5.3/5.4
# Throttle chain (thesis 3.1.1): V = sp/20, 1.5 V deadband, 4.5 V full.
def mapped(sp):
    v = abs(sp) / 20.0
    return max(0.0, min(100.0, (v - 1.5) / 3.0 * 100.0))

SPEED_FWD = [(0, 0), (2, 200), (10, 420), (20, 680), (30, 940), (40, 1190), (50, 1440),
             (60, 1690), (70, 1930), (75, 2050), (80, 2100), (100, 2100)]
SPEED_REV = [(0, 0), (2, 80), (10, 130), (20, 190), (40, 310), (60, 420), (70, 470),
             (75, 490), (80, 500), (100, 500)]

def interp(tab, x):
    if x <= tab[0][0]:
        return tab[0][1]
    for (x0, y0), (x1, y1) in zip(tab, tab[1:]):
        if x <= x1:
            return y0 + (y1 - y0) * (x - x0) / (x1 - x0)
    return tab[-1][1]

def motor_rpm(thr_sp):
    m = mapped(thr_sp)
    return math.copysign(interp(SPEED_FWD if thr_sp >= 0 else SPEED_REV, m), thr_sp) if m > 0 else 0.0

# Axle friction: cubic near zero, linear outside (thesis 5.3.1), odd-symmetric, with a
# step at the ends where the motor limits are reached (fig. 5.24/5.25). L != R.
FRICTION = {"L": dict(t0=8.0, b=0.090), "R": dict(t0=8.1, b=0.092)}
W_T = 20.0        # cubic/linear threshold [rpm], assumed (thesis optimises it; value not given)
W_STEP = 200.0    # speed beyond the measured 190 rpm where the end step starts [rpm]
STEP = 10.0       # end-step height [N m]

def friction(side, w):
    p = FRICTION[side]
    a_w = abs(w)
    if a_w <= W_T:
        c = (p["b"] * W_T - p["t0"]) / (2 * W_T ** 3)
        a = p["b"] - 3 * c * W_T ** 2
        t = a * a_w + c * a_w ** 3
    else:
        t = p["t0"] + p["b"] * (a_w - W_T)
    if a_w >= W_STEP:
        t += STEP * min(1.0, (a_w - W_STEP) / 5.0)
    return math.copysign(t, w) if w != 0 else 0.0

# Load motors (thesis 5.2.2): current saturates near +-60 A, axle torque limits near 60 %
# set point regenerating and 100 % motoring. Convention of these maps: positive torque
# = regenerating (the load absorbs power), positive phase current = motoring.
T_LOAD_MAX = 80.0     # axle torque at the limit [N m], assumed from the power limits
SIDE_GAIN = {"L": 1.0, "R": 0.98}   # "L and R nearly equal"

def load_torque(side, load_sp, thr_sp):
    if load_sp >= 0:
        t = T_LOAD_MAX * min(load_sp / 60.0, 1.0)
    else:
        t = -T_LOAD_MAX * min(-load_sp / 100.0, 1.0)
    g = 1.0 - 0.1 * max(0.0, (abs(thr_sp) - 60.0) / 40.0)   # field weakening at speed
    drag = 2.0 * max(0.0, (abs(thr_sp) - 70.0) / 30.0)       # back-EMF drag, fig. 5.8
    return SIDE_GAIN[side] * t * g + drag

def load_current(side, load_sp, thr_sp):
    if load_sp >= 0:
        i = -60.0 * min(load_sp / 60.0, 1.0)
    else:
        i = 60.0 * min(-load_sp / 100.0, 1.0)
    i -= 5.0 * max(0.0, (abs(thr_sp) - 70.0) / 30.0)         # fig. 5.8: current at SuT limits
    return SIDE_GAIN[side] * i

ETA_LOAD = 0.85       # load motor + inverter efficiency, assumed
R_PHASE = 0.03        # load motor copper resistance [ohm], assumed
P_IDLE_LOAD = 15.0    # load inverter idle power [W], assumed
P_LOAD_LIM = (-1100.0, 1250.0)   # thesis 5.5

def axle_rad_s(thr_sp):
    return motor_rpm(thr_sp) / GEAR * math.pi / 30.0

def load_power(side, load_sp, thr_sp):
    w = abs(axle_rad_s(thr_sp))
    t = load_torque(side, load_sp, thr_sp)
    p_abs = t * w                      # mechanical power absorbed from the shaft
    p = -ETA_LOAD * p_abs if p_abs >= 0 else -p_abs / ETA_LOAD
    i = load_current(side, load_sp, thr_sp)
    p += P_IDLE_LOAD + R_PHASE * i * i
    return max(P_LOAD_LIM[0], min(P_LOAD_LIM[1], p))

ETA_SUT = 0.72        # SuT motor + inverter efficiency at the operating points, assumed
P_IDLE_SUT = 40.0     # SuT inverter idle power [W], assumed
P_SUT_LIM = (-1600.0, 6000.0)    # thesis 5.5

def sut_power(thr_sp, load_sp):
    w = axle_rad_s(thr_sp)
    t_axle = 0.0
    for side in "LR":
        w_rpm = w * 30.0 / math.pi
        t_axle += abs(friction(side, w_rpm)) + load_torque(side, load_sp, thr_sp)
    p_mech = t_axle * abs(w)
    p = p_mech / ETA_SUT if p_mech >= 0 else p_mech * ETA_SUT
    p += P_IDLE_SUT
    return max(P_SUT_LIM[0], min(P_SUT_LIM[1], p))

THR_GRID = [-100, -90, -80, -70, -60, -50, -40, -35, -30, 0, 30, 35, 40, 50, 60, 70, 80, 90, 100]
LOAD_GRID = [-100, -80, -60, -40, -20, 0, 20, 40, 60, 80, 100]

HEADER = ("# Synthesized by tools/synth_maps.py: the thesis gives this map only as a figure.\n"
          "# Replace with identified data (`simrod identify`) and rebuild.\n")

def write(name, text):
    with open(os.path.join(OUT, name), "w") as f:
        f.write(text)

def fmt(v):
    s = f"{v:.4f}".rstrip("0").rstrip(".")
    return "0" if s in ("-0", "") else s

def table1(name, what, xname, xunit, yname, yunit, pts):
    lines = [HEADER, f"# {what}\n", f"{xname} [{xunit}],{yname} [{yunit}]\n"]
    lines += [f"{fmt(x)},{fmt(y)}\n" for x, y in pts]
    write(name, "".join(lines))

def table2(name, what, unit, f):
    lines = [HEADER, f"# {what}\n",
             f"# rows: load set point [%]; columns: throttle set point [%]; values: [{unit}]\n",
             "load_sp\\throttle_sp," + ",".join(fmt(x) for x in THR_GRID) + "\n"]
    for l in LOAD_GRID:
        lines.append(fmt(l) + "," + ",".join(fmt(f(l, t)) for t in THR_GRID) + "\n")
    write(name, "".join(lines))

def main():
    table1("speed_map_fwd.csv", "SuT target speed vs mapped throttle, forward (fig. 5.7; limit 2100 rpm, table 5.3)",
           "mapped_throttle", "%", "speed", "rpm", SPEED_FWD)
    table1("speed_map_rev.csv", "SuT target speed magnitude vs mapped throttle, reverse (fig. 5.7; limit 500 rpm, table 5.3)",
           "mapped_throttle", "%", "speed", "rpm", SPEED_REV)
    grid = [0, 2, 4, 6, 8, 10, 12, 14, 16, 18, 20, 30, 50, 100, 150, 190, 200, 205, 250]
    for side in "LR":
        pts = [(-w, friction(side, -w)) for w in reversed(grid[1:])] + [(w, friction(side, w)) for w in grid]
        table1(f"axle_friction_{side}.csv",
               f"Axle friction torque, side {side}: cubic near zero, linear outside, odd-symmetric, end step (5.3.1, fig. 5.24/5.25)",
               "axle_speed", "rpm", "torque", "N m", pts)
        table2(f"load_torque_{side}.csv",
               f"Load motor {side} axle torque, + = regenerating (absorbs), - = motoring (fig. 5.14/5.15)",
               "N m", lambda l, t, s=side: load_torque(s, l, t))
        table2(f"load_current_{side}.csv",
               f"Load motor {side} phase current, + = motoring (fig. 5.10/5.11; +-60 A)",
               "A", lambda l, t, s=side: load_current(s, l, t))
        table2(f"load_power_{side}.csv",
               f"Load motor {side} electrical power at the busbars, + = drawn (fig. 5.46/5.47; -1100..+1250 W)",
               "W", lambda l, t, s=side: load_power(s, l, t))
    table2("sut_inverter_power.csv",
           "SuT inverter electrical power, + = drawn (fig. 5.42/5.43; -1600..+6000 W)",
           "W", lambda l, t: sut_power(t, l))

if __name__ == "__main__":
    main()
