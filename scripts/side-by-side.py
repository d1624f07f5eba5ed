#!/usr/bin/env python3
"""Climbs side by side (the truth or the robot's own estimate, the model's body or one unlike
it), as a Markdown table: per row, runs, passed, the friction ratio and the CoM margin over
the runs that climbed (median / worst), and the estimate's largest error at a sweep.

Usage:
  scripts/side-by-side.py ROW... [--write BENCHMARKS.md]

Each ROW is LABEL=PATH[,PATH...]: a PATH is a `regress` results.jsonl, or a folder of `run
--json` reports (*.json, one per run); a row counts the runs of all its paths. With --write, the table replaces the section between
`<!-- side-by-side -->` and `<!-- /side-by-side -->` in that file, with the command that made
it, as the bench's own `--write` does."""
import glob
import json
import os
import statistics
import sys


def runs(path):
    """(passed, climbed clean, friction, margin_m, estimate_m, estimate_rad, climbed) per run; a
    run climbed with every check clean whether or not its estimate strayed."""
    out = []
    if os.path.isdir(path):
        for f in sorted(glob.glob(os.path.join(path, "*.json"))):
            d = json.load(open(f))
            errs = [c["estimate_error"] for c in d.get("cycles", []) if c.get("estimate_error")]
            out.append((d["success"], d["success"], d.get("max_friction_ratio"), d.get("min_margin_m"),
                        max((e["position_m"] for e in errs), default=None),
                        max((abs(e["yaw_rad"]) for e in errs), default=None), d["success"]))
    else:
        for line in open(path):
            r = json.loads(line)
            out.append((r["pass"], r["verdict"] == "climbed_clean", r.get("max_friction_ratio"), r.get("min_margin_m"),
                        r.get("max_estimate_error_m"), r.get("max_estimate_yaw_rad"),
                        r["verdict"] in ("climbed_clean", "estimate_strayed")))
    return out


def row(label, rs):
    climbed = [r for r in rs if r[6] and r[2] is not None and r[3] is not None]
    fr = [r[2] for r in climbed]
    mm = [r[3] * 1e3 for r in climbed]
    est = [r[4] for r in rs if r[4] is not None]
    yaw = [r[5] for r in rs if r[5] is not None]
    cell = lambda xs, worst, f: f"{statistics.median(xs):{f}} / {worst(xs):{f}}" if xs else "-"  # noqa: E731
    estimate = f"{max(est) * 1e3:.1f} mm / {max(yaw) * 57.29577951308232:.2f} deg" if est else "- (the truth)"
    return (f"| {label} | {len(rs)} | {sum(r[0] for r in rs)} | {sum(r[1] for r in rs)} | {cell(fr, max, '.3f')} | "
            f"{cell(mm, min, '.1f')} | {estimate} |")


def table(args):
    lines = ["| what | runs | passed | climbed clean | friction ratio (median / largest) | "
             "CoM margin mm (median / least) | estimate's largest error at a sweep |",
             "|---|---|---|---|---|---|---|"]
    for a in args:
        label, _, path = a.partition("=")
        lines.append(row(label, [r for p in path.split(",") for r in runs(p)]))
    return "\n".join(lines)


def main():
    args = sys.argv[1:]
    write = None
    if "--write" in args:
        i = args.index("--write")
        write = args[i + 1]
        args = args[:i] + args[i + 2:]
    if not args or any("=" not in a for a in args):
        sys.exit(__doc__)
    t = table(args)
    if not write:
        print(t)
        return
    text = open(write).read()
    start, end = "<!-- side-by-side -->", "<!-- /side-by-side -->"
    if start not in text or end not in text:
        sys.exit(f"{write} has no {start} ... {end} section")
    cmd = "Command: `scripts/side-by-side.py " + " ".join(f"'{a}'" for a in args) + f" --write {write}`"
    a, b = text.index(start) + len(start), text.index(end)
    open(write, "w").write(text[:a] + "\n" + cmd + "\n\n" + t + "\n" + text[b:])


if __name__ == "__main__":
    main()
