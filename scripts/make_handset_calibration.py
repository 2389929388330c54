#!/usr/bin/env python3
"""Writes calibrations/kr30ha-handset.json: a HAND-SET, plausible calibration of the paper's full
model (geometric, map:A1..A6, backlash:A1..A6, crosstalk:A3->A2) for examples, snapshots and
benchmarks until identification from measurements exists. The magnitudes follow the paper's
figures (axis-line errors of tenths of a millimetre and thousandths of a degree, angular
deviations of about ±0.01 deg with cyclic gear errors, backlash a few thousandths of a degree);
the values themselves are made up and deterministic. Not a measured robot."""
import json, math, re, sys

LIMITS = [[-185.0, 185.0], [-135.0, 35.0], [-120.0, 158.0], [-350.0, 350.0], [-119.0, 119.0], [-350.0, 350.0]]

def grid(lo, hi, pitch):
    pts = []
    x = lo
    while x < hi - 1e-9:
        pts.append(x)
        x += pitch
    return pts + [hi]

def r(x):
    return float(f"{x:.6f}")

geometric = {
    "dx21": 0.12, "a21": 0.004, "dth20": 0.010, "dz32": -0.08, "a32": 0.003, "g32": -0.002,
    "dth30": -0.012, "dz43": 0.05, "dy43": 0.07, "g43": 0.004, "dth40": 0.020, "dx54": -0.06,
    "dz54": 0.04, "g54": -0.003, "dth50": 0.015, "dz65": 0.03, "dy65": -0.02, "g65": 0.005,
}
effects = [{"name": "geometric", "parameters": geometric}]
# map:An — a slow trend plus a cyclic gear error (periods of 30..90 deg), degrees.
for n in range(6):
    lo, hi = LIMITS[n]
    g = grid(lo, hi, 5.0)
    amp = [0.008, 0.012, 0.010, 0.015, 0.012, 0.015][n]
    period = [60.0, 45.0, 50.0, 90.0, 40.0, 75.0][n]
    vals = [r(amp * math.sin(2 * math.pi * x / period + n) + 0.3 * amp * x / (hi - lo)) for x in g]
    effects.append({"name": f"map:A{n+1}", "table": {"grid_deg": g, "values_deg": vals}})
# backlash:An — the gear play's width, degrees: the output lags the command by half of it, so
# after a positive move the axis stands short (Δθ(+1) < Δθ(−1)).
for n in range(6):
    lo, hi = LIMITS[n]
    g = grid(lo, hi, 10.0)
    base = [0.004, 0.005, 0.004, 0.006, 0.005, 0.006][n]
    vals = [r(2.0 * base * (1.0 + 0.2 * math.cos(math.radians(x) * 2 + n))) for x in g]
    effects.append({"name": f"backlash:A{n+1}", "table": {"grid_deg": g, "values_deg": vals}})
# crosstalk:A3->A2 — A2's deviation changes with A3 (paper: tested at A3 = 58, 105, 153 deg).
g2 = grid(-135.0, 35.0, 5.0)
g3 = [58.0, 105.0, 153.0]
vals = []
for a2 in g2:
    for a3 in g3:
        vals.append(r(0.004 * math.sin(math.radians(a2) * 1.5) * (a3 - 105.0) / 48.0))
effects.append({"name": "crosstalk:A3->A2", "table": {"grid_deg": g2, "other_grid_deg": g3, "values_deg": vals}})

cal = {
    "format": "robopost-calibration/2",
    "robot": {
        "name": "KR 30 HA",
        "description": {
            "links": {"l1x": 350.0, "l1z": 815.0, "l2": 850.0, "l3z": 145.0, "l4x": 820.0, "l5x": 170.0},
            "limits_deg": LIMITS,
            "senses": [-1.0, 1.0, 1.0, -1.0, 1.0, -1.0],
            "offsets_deg": [0.0, 90.0, -90.0, 0.0, 0.0, 0.0],
            "gravity": {
                "link_mass_kg": [240.0, 110.0, 95.0, 25.0, 12.0, 3.0],
                "link_cog_mm": [[120.0, 0.0, 300.0], [0.0, 0.0, 400.0], [250.0, 0.0, 120.0], [350.0, 0.0, 0.0], [60.0, 0.0, 0.0], [20.0, 0.0, 0.0]],
            },
        },
    },
    "target_mm": [0.0, 0.0, 0.0],
    "frame": "base",
    "effects": effects,
    "provenance": {
        "notes": "HAND-SET, NOT MEASURED: plausible values of the paper's full model (geometric, map:A1..A6, backlash:A1..A6, crosstalk:A3->A2) written by scripts/make_handset_calibration.py for examples, snapshots and benchmarks until a calibration identified from laser-tracker data exists. Do not use it on a real robot."
    },
}
out = sys.argv[1] if len(sys.argv) > 1 else "calibrations/kr30ha-handset.json"
text = json.dumps(cal, indent=2)
# Arrays of numbers (and of small number arrays) on one line, like the nominal calibration.
num_list = re.compile(r"\[\s*(-?[0-9.e+-]+(?:,\s*-?[0-9.e+-]+)*)\s*\]")
text = num_list.sub(lambda m: "[" + ", ".join(x.strip() for x in m.group(1).split(",")) + "]", text)
text = re.compile(r"\[\s*(\[[^\[\]]*\](?:,\s*\[[^\[\]]*\])*)\s*\]").sub(lambda m: "[" + re.sub(r",\s*\[", ", [", m.group(1)) + "]", text)
with open(out, "w") as f:
    f.write(text + "\n")
