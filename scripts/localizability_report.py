#!/usr/bin/env python3
"""How well `visloc map localizability` predicted what localization really did: the tables of
docs/localizability.md.

Each run joins a localization's per-frame stats CSV (visloc localize --stats) with the prediction
at each frame's pose (PREFIX.path.csv of `map localizability --at POSES.tum`): the prediction at
the pose itself, and the grid's value at its cell and nearest heading (what the operator sees).
Frames a sequence lists as covered or blank (a hand over the lens is not a property of the place)
are left out and counted.

Usage: localizability_report.py MANIFEST > rows.md
MANIFEST: one run a line, tab-separated: GROUP NAME PATH_CSV STATS_CSV [SEQUENCE_JSON]
Prints the markdown tables (per run, then pooled per group) and, on stderr, one JSON object.
"""

import csv
import json
import math
import sys


def ranks(values):
    order = sorted(range(len(values)), key=lambda i: values[i])
    r = [0.0] * len(values)
    i = 0
    while i < len(order):
        j = i
        while j + 1 < len(order) and values[order[j + 1]] == values[order[i]]:
            j += 1
        for k in range(i, j + 1):
            r[order[k]] = (i + j) / 2.0
        i = j + 1
    return r


def spearman(a, b):
    if len(a) < 3:
        return None
    ra, rb = ranks(a), ranks(b)
    ma, mb = sum(ra) / len(ra), sum(rb) / len(rb)
    cov = sum((x - ma) * (y - mb) for x, y in zip(ra, rb))
    va = sum((x - ma) ** 2 for x in ra)
    vb = sum((y - mb) ** 2 for y in rb)
    return cov / math.sqrt(va * vb) if va > 0 and vb > 0 else None


def load_run(path_csv, stats_csv, sequence_json):
    skip = set()
    if sequence_json:
        seq = json.load(open(sequence_json))
        skip = set(seq.get("covered_frames", [])) | set(seq.get("blank_frames", []))
    predicted = {int(r["timestamp_ns"]): r for r in csv.DictReader(open(path_csv))}
    frames, skipped = [], 0
    for index, row in enumerate(csv.DictReader(open(stats_csv))):
        if index in skip:
            skipped += 1
            continue
        p = predicted.get(int(row["timestamp_ns"]))
        if p is None:
            continue
        frames.append({
            "pred": float(p["expected_inliers"]), "cell": float(p["cell_expected_inliers"]),
            "actual": float(row["inliers"]), "status": row["status"],
            "good": p["good"] == "1", "cell_good": p["cell_good"] == "1"})
    return frames, skipped


def figures(frames):
    def share(flags):
        return sum(flags) / len(flags) if flags else None

    poor = [f for f in frames if f["status"] in ("lost", "limited")]
    out = {"frames": len(frames), "lost_or_limited": len(poor)}
    for key, good in (("pose", "good"), ("cell", "cell_good")):
        pred = [f["pred" if key == "pose" else "cell"] for f in frames]
        out[f"spearman_{key}"] = spearman(pred, [f["actual"] for f in frames])
        out[f"poor_predicted_poor_{key}"] = share([not f[good] for f in poor])
        predicted_good = [f for f in frames if f[good]]
        out[f"predicted_good_{key}"] = len(predicted_good)
        out[f"predicted_good_localized_{key}"] = share(
            [f["status"] in ("tracking", "relocalized") for f in predicted_good])
    tracked = sorted(f["actual"] / f["pred"] for f in frames
                     if f["status"] == "tracking" and f["pred"] > 0)
    out["actual_over_predicted_median"] = tracked[len(tracked) // 2] if tracked else None
    return out


def cell(value, percent=False):
    if value is None:
        return "-"
    return f"{100 * value:.0f}%" if percent else f"{value:.2f}"


def row(label, f, skipped=None):
    skip = f" ({skipped} covered left out)" if skipped else ""
    return (f"| {label}{skip} | {f['frames']} | {f['lost_or_limited']} | "
            f"{cell(f['spearman_pose'])} / {cell(f['spearman_cell'])} | "
            f"{cell(f['poor_predicted_poor_pose'], True)} / {cell(f['poor_predicted_poor_cell'], True)} | "
            f"{f['predicted_good_pose']} / {f['predicted_good_cell']} | "
            f"{cell(f['predicted_good_localized_pose'], True)} / {cell(f['predicted_good_localized_cell'], True)} | "
            f"{cell(f['actual_over_predicted_median'])} |")


def main(manifest):
    groups, report = {}, {"runs": [], "groups": {}}
    print("| run | frames | lost or limited | Spearman, predicted vs actual inliers (pose / cell) "
          "| lost or limited predicted poor (pose / cell) | predicted good (pose / cell) "
          "| of those, localized (pose / cell) | actual / predicted inliers, median |")
    print("|---|---|---|---|---|---|---|---|")
    for line in open(manifest):
        fields = line.rstrip("\n").split("\t")
        if len(fields) < 4:
            continue
        group, name, path_csv, stats_csv = fields[:4]
        frames, skipped = load_run(path_csv, stats_csv, fields[4] if len(fields) > 4 else "")
        f = figures(frames)
        print(row(f"{group}: {name}", f, skipped))
        report["runs"].append({"group": group, "name": name, **f})
        groups.setdefault(group, []).extend(frames)
    for group, frames in groups.items():
        f = figures(frames)
        print(row(f"**{group}: all walks pooled**", f))
        report["groups"][group] = f
    print(json.dumps(report), file=sys.stderr)


if __name__ == "__main__":
    main(sys.argv[1])
