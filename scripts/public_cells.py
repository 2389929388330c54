#!/usr/bin/env python3
"""Measures robopost's main job on robot cells it has never seen: for each cell tree given
(a checked-out public repository holding a KUKA KRC backup or project), every `.src` with
motion statements outside the controller's own folders runs as the main program with `--cell`
the tree's root and `--points auto`, and the table says what happened to it: programs
compensated, programs refused and why (grouped by the first words of the error), targets taken
as taught and as offline, and what `--assume NAME=VALUE` recovers where a program was refused
because a value is known only at run time (the first value of an integer, TRUE of a boolean:
one station of several, as a user would run once per station).

The hand-set error model (`calibrations/kr30ha-handset.json`'s effects) is put on the cell's
robot: where the tree's machine data name another robot, its links replace the KR 30 HA's (the
effects are the same hand-set numbers; the counts here do not depend on their size).

Usage: scripts/public_cells.py [--bin target/release/robopost] CELL_DIR... > table.md
Nothing of the cells is copied anywhere: outputs go to a temporary directory.
"""
import argparse
import collections
import json
import os
import re
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SKIP = {"system", "tp", "template", "steu", "mada"}
MOTION = re.compile(rb"^\s*(PTP|LIN|CIRC|SPL|SLIN|SCIRC|SPTP|PTP_REL|LIN_REL)\b", re.I | re.M)
MISMATCH = re.compile(
    r"machine data (.+?) says the robot is a (.+?) \(l1x (\S+) l1z (\S+) l2 (\S+) l3z (\S+) "
    r"l4x (\S+) l5x (\S+) mm\)"
)
RUN_TIME = re.compile(
    r"depends on run time \((?:the run-time value )?([A-Za-z_$][\w$]*(?:\[[^\]]*\])?)"
)


def programs(root):
    out = []
    for d, dirs, files in os.walk(root):
        dirs[:] = sorted(x for x in dirs if x.lower() not in SKIP and not x.startswith("."))
        for f in sorted(files):
            if f.lower().endswith(".src"):
                p = os.path.join(d, f)
                with open(p, "rb") as fh:
                    if MOTION.search(fh.read()):
                        out.append(p)
    return out


def run(binary, args):
    r = subprocess.run([binary] + args, capture_output=True, timeout=600)
    return r.returncode, r.stderr.decode("utf-8", "replace")


def calibration_for(binary, root, prog, tmp):
    """The hand-set calibration on the cell's robot, and the robot's name."""
    handset = os.path.join(ROOT, "calibrations", "kr30ha-handset.json")
    code, err = run(binary, ["check", "--cell", root, "-c", handset, prog])
    m = MISMATCH.search(err)
    if not m:
        other = re.search(r"the robot (\S+) is not one", err)
        if other:
            return handset, f"{other.group(1)} (machine data: not modelled)"
        return handset, "none stated (KR 30 HA assumed)"
    with open(handset) as fh:
        cal = json.load(fh)
    links = dict(zip(["l1x", "l1z", "l2", "l3z", "l4x", "l5x"], map(float, m.groups()[2:])))
    cal["robot"]["name"] = m.group(2)
    cal["robot"]["description"]["links"] = links
    path = os.path.join(tmp, "cal.json")
    with open(path, "w") as fh:
        json.dump(cal, fh)
    return path, m.group(2) + " (machine data)"


def reason(err):
    """The refusal's reason: the first error line, numbers and names masked, cut short."""
    for line in err.splitlines():
        if line.startswith("error"):
            text = re.sub(r"^.+?\.(src|dat|SRC|DAT)(:\d+)*: ", "", line[len("error: "):])
            text = re.sub(r"`[^`]*`|\"[^\"]*\"", "…", text)
            text = re.sub(r"\d+(\.\d+)?", "N", text)
            return text[:90]
    return "(no error line)"


def assumptions(err):
    """Every value the walk said only run time knows, each assumed: TRUE for an input or
    output, 1 for anything else (the first station, the first case)."""
    names = []
    for m in RUN_TIME.finditer(err):
        name = m.group(1)
        if name.upper() not in (n.upper() for n in names):
            names.append(name)
    out = []
    for name in names:
        value = "TRUE" if name.upper().startswith(("$IN[", "$OUT[")) else "1"
        out += ["--assume", f"{name}={value}"]
    return out


def job(binary, root, prog, cal, tmp, extra=()):
    out = os.path.join(tmp, "out.src")
    rep = os.path.join(tmp, "report.json")
    for p in (out, out[:-4] + ".dat", rep):
        if os.path.exists(p):
            os.remove(p)
    code, err = run(binary, [prog, "--cell", root, "-c", cal, "-o", out, "--report", rep, *extra])
    report = None
    if os.path.exists(rep):
        with open(rep) as fh:
            report = json.load(fh)
    return code, err, report


def refused(code, report):
    """Refused whole (exit 2, no report), or ran with errors and nothing compensated."""
    if code == 2 or report is None:
        return True
    return bool(report.get("errors")) and report.get("compensated", 0) == 0 and code != 0


def measure(binary, root):
    progs = programs(root)
    row = collections.Counter()
    reasons = collections.Counter()
    with tempfile.TemporaryDirectory() as tmp:
        cal, robot = calibration_for(binary, root, progs[0], tmp) if progs else (None, "-")
        for prog in progs:
            row["programs"] += 1
            code, err, rep = job(binary, root, prog, cal, tmp)
            if refused(code, rep):
                row["refused"] += 1
                reasons[reason(err)] += 1
                a = assumptions(err)
                if a:
                    row["assume_tried"] += 1
                    code2, _, rep2 = job(binary, root, prog, cal, tmp, a)
                    if not refused(code2, rep2):
                        row["assume_recovered"] += 1
                        row["assume_targets"] += rep2.get("compensated", 0)
                continue
            row["ran"] += 1
            row["targets"] += rep.get("targets", 0)
            row["compensated"] += rep.get("compensated", 0)
            taken = rep.get("points_taken") or {}
            row["taught"] += taken.get("taught", 0)
            row["offline"] += taken.get("offline", 0)
    return robot, row, reasons


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--bin", default=os.path.join(ROOT, "target", "release", "robopost"))
    ap.add_argument("cells", nargs="+")
    a = ap.parse_args()
    print("| cell | robot | programs | refused or nothing compensated | targets of the others "
          "| taken as taught | as offline | compensated "
          "| refused on a run-time value → run with `--assume` (targets compensated) |")
    print("|---|---|---|---|---|---|---|---|---|")
    total = collections.Counter()
    all_reasons = collections.Counter()
    for cell in [c for c in a.cells if os.path.isdir(c)]:
        robot, row, reasons = measure(a.bin, cell)
        total.update(row)
        all_reasons.update(reasons)
        name = os.path.basename(os.path.normpath(cell)).replace("+", "/")
        print(f"| {name} | {robot} | {row['programs']} | {row['refused']} | {row['targets']} "
              f"| {row['taught']} | {row['offline']} | {row['compensated']} "
              f"| {row['assume_tried']} → {row['assume_recovered']} ({row['assume_targets']}) |")
        sys.stdout.flush()
    print(f"| **all** | | **{total['programs']}** | **{total['refused']}** | **{total['targets']}** "
          f"| **{total['taught']}** | **{total['offline']}** | **{total['compensated']}** "
          f"| **{total['assume_tried']} → {total['assume_recovered']} ({total['assume_targets']})** |")
    print()
    print("| programs refused | why (first error, numbers and names masked) |")
    print("|---|---|")
    for why, n in all_reasons.most_common():
        print(f"| {n} | {why} |")


if __name__ == "__main__":
    main()
