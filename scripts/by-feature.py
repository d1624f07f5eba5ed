#!/usr/bin/env python3
"""The `real` suite's results by feature of real stairs, as a Markdown table.

Usage: scripts/by-feature.py out/regress/real/results.jsonl [--write BENCHMARKS.md]

With --write, the table replaces the section between `<!-- real-by-feature -->` and
`<!-- /real-by-feature -->` in that file (with the command that made it: `--seeds N` when the results hold N draws), as the bench's own
`--write` does.

A run counts under every feature its case has (nosing, open risers, uneven rises or treads,
handrails, objects on treads), and under "plain" when it has none. Friction ratio and CoM
margin are over the runs that climbed (median / worst)."""
import json
import statistics
import sys

# Verdicts of a run that climbed with every check clean.
CLIMBED = ("climbed_clean", "estimate_strayed")


def features(p):
    f = []
    if p.get("nosing_m", 0) > 0:
        f.append("nosings")
    if p.get("risers") == "open":
        f.append("open risers")
    if p.get("rise_jitter_m", 0) > 0 or p.get("odd_step", "none") != "none" or p.get("tread_jitter_m", 0) > 0:
        f.append("uneven rises or treads")
    if p.get("handrails", "none") != "none":
        f.append("handrails")
    if p.get("objects", 0) > 0:
        f.append("objects on treads")
    return f or ["plain"]


def table(path):
    out = []
    print = lambda s="": out.append(s)  # noqa: E731 (the table is collected, not printed)
    rows = {}
    for line in open(path):
        r = json.loads(line)
        for f in features(r["params"]):
            rows.setdefault(f, []).append(r)
    order = ["nosings", "open risers", "uneven rises or treads", "handrails", "objects on treads", "plain"]
    print("| feature | runs | passed | climbed clean | refused as expected | friction ratio (median / largest) | CoM margin mm (median / least) |")
    print("|---|---|---|---|---|---|---|")
    for f in order + [k for k in rows if k not in order]:
        rs = rows.get(f, [])
        if not rs:
            continue
        # The forces and margins of every run that climbed with its checks clean, its estimate
        # too far off (`estimate_strayed`) or not.
        climbed = [r for r in rs if r["verdict"] in CLIMBED]
        fr = [r["max_friction_ratio"] for r in climbed]
        mg = [r["min_margin_m"] * 1e3 for r in climbed if r["min_margin_m"] is not None]
        fmt = lambda xs, worst: f"{statistics.median(xs):.3f} / {worst(xs):.3f}" if xs else "-"
        fmtm = lambda xs: f"{statistics.median(xs):.1f} / {min(xs):.1f}" if xs else "-"
        print(f"| {f} | {len(rs)} | {sum(r['pass'] for r in rs)} | {sum(r['verdict'] == 'climbed_clean' for r in rs)} | "
              f"{sum(r['verdict'] == 'refused_as_expected' for r in rs)} | {fmt(fr, max)} | {fmtm(mg)} |")
    allr = [json.loads(l) for l in open(path)]
    print(f"\nall: {sum(r['pass'] for r in allr)} of {len(allr)} passed; falls "
          f"{sum(r['verdict'] == 'fell' for r in allr)}, errors {sum(r['verdict'] == 'error' for r in allr)}, "
          f"timeouts {sum(r['verdict'] == 'timeout' for r in allr)}")
    return "\n".join(out) + "\n"


def write(md, text, seeds):
    begin, end = "<!-- real-by-feature -->", "<!-- /real-by-feature -->"
    doc = open(md).read()
    if begin not in doc or end not in doc:
        sys.exit(f"{md} has no {begin} ... {end} section to replace")
    head, rest = doc.split(begin, 1)
    _, tail = rest.split(end, 1)
    draws = f" --seeds {seeds}" if seeds > 1 else ""
    cmd = (f"Command: `./target/release/stairbench regress real{draws} --out DIR --jobs 2`, then "
           "`scripts/by-feature.py DIR/results.jsonl --write BENCHMARKS.md`\n\n")
    open(md, "w").write(head + begin + "\n" + cmd + text + end + tail)


if __name__ == "__main__":
    args = sys.argv[1:]
    if len(args) == 3 and args[1] == "--write":
        seeds = max((json.loads(l).get("seeds", 1) for l in open(args[0])), default=1)
        write(args[2], table(args[0]), seeds)
    elif len(args) == 1:
        sys.stdout.write(table(args[0]))
    else:
        sys.exit(__doc__)
