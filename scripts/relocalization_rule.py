#!/usr/bin/python3
"""Replays relocalization acceptance rules on recorded evidence and picks one.

Input: the jobs file of scripts/relocalization-rule.sh (kind, recording, map, query, evidence TSV,
ground truth TUM or '-', the map's keyframes TUM or '-') and each job's evidence TSV
(`visloc relocalize --evidence`: every candidate of both feature passes, verified with no rule).

A rule accepts a candidate whose RANSAC found a pose with at least `ransac` inliers (among at least
20 descriptor matches) and whose verification has at least `inliers` inliers, an inlier ratio of
at least `ratio`, a significance (-log10 of the chance of that many inliers, less log10 of the
candidates) of at least `significance` and inliers in at least `cells` cells of the 8x6 grid.
It is replayed as the relocalizer decides: the first feature pass, and the second only when the
first accepted nothing; within a pass the candidates in rank order, the best-supported accepted
one kept, and the search stopped after an accepted candidate with 80 inliers or more in at least
`strong_cells` cells.

A positive frame's pose is judged against its truth (relocalization-rule.sh: the ground truth, as
the map sees it): found within 5 cm and 2 degrees; off beyond that but within 1 m and 10 degrees
(the right place, imprecisely: a drive's poses along the road); wrong beyond (another place).
A wrong pose, and any pose taken on a negative frame, is a false positive.

The rule is chosen to hold beyond these frames, not to fit them (the rule it replaces was set where
one split's frames passed, and refused true fixes on others): the inlier ratio gate is dropped
(true fixes on real frames re-match many points to a wrong corner, and a wrong place in a room
like the map's reaches a ratio of 0.7), RANSAC keeps 15 inliers and the verification at least 30
(what a session calls a strong fix); the significance threshold is the grid's largest value at
or below the geometric mean of the strongest negative's significance and the weakest found
positive's (the widest margin on both sides, rounded towards the positives: true fixes on
frames these splits do not hold are weaker than theirs, as the rule it replaces showed); the early stop's coverage is the value with the fewest poses off.
The choice must have no false positive and find as many as any rule of the grid, or the script
fails.
"""

import argparse
import collections
import itertools
import math
import sys

import numpy as np

MAX_POSITION_ERROR_M = 0.05  # Found.
MAX_ROTATION_ERROR_DEG = 2.0
WRONG_POSITION_M = 1.0  # Beyond either: another place.
WRONG_ROTATION_DEG = 10.0
STRONG_INLIERS = 80
# Descriptor matches a candidate needs before RANSAC (RelocalizationOptions::min_matches).
MIN_MATCHES = 20
# (RANSAC inliers, verified inliers, ratio, significance, cells, strong cells) of the rule
# before this choice.
PREVIOUS_RULE = (15, 40, 0.5, 0.0, 0, 0)


def quat_to_matrix(w, x, y, z):
    n = math.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / n, x / n, y / n, z / n
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def read_tum(path):
    """timestamp (ns) -> (R, t) of a TUM file (seconds, tx ty tz qx qy qz qw)."""
    poses = {}
    with open(path) as f:
        for line in f:
            if line.startswith('#') or not line.strip():
                continue
            v = [float(x) for x in line.split()]
            poses[int(round(v[0] * 1e9))] = (quat_to_matrix(v[7], v[4], v[5], v[6]),
                                             np.array(v[1:4]))
    return poses


class Poses:
    """A TUM trajectory (or none), looked up by time."""

    def __init__(self, path):
        self.poses = read_tum(path) if path != '-' else {}
        self.stamps = np.array(sorted(self.poses))
        positions = np.array([t for _, t in self.poses.values()])
        # A camera at rest (every position within 1 cm of their mean: EuRoC V1_01 micro) is
        # where its ground truth is, before the ground truth starts too.
        self.at_rest = len(positions) > 0 and bool(
            np.linalg.norm(positions - positions.mean(axis=0), axis=1).max() < 0.01)

    def __bool__(self):
        return bool(self.poses)

    def nearest_stamp(self, t_ns):
        return int(self.stamps[np.argmin(np.abs(self.stamps - t_ns))])

    def at(self, t_ns, tolerance_ns=2_000_000):
        """The pose at t_ns, within the tolerance (for a camera at rest, the nearest); or None."""
        if not self:
            return None
        if self.at_rest:
            t_ns = min(max(t_ns, self.stamps[0]), self.stamps[-1])
        best = self.nearest_stamp(t_ns)
        return self.poses[best] if abs(best - t_ns) <= tolerance_ns else None


class Job:
    """One (map, query) pair's evidence as arrays over [frame, pass, rank]."""

    def __init__(self, kind, recording, map_name, query, evidence, gt, anchor):
        self.kind, self.recording, self.map, self.query = kind, recording, map_name, query
        rows = collections.defaultdict(dict)
        frames = {}
        ranks = 1
        with open(evidence) as f:
            header = f.readline().rstrip('\n').split('\t')
            for line in f:
                r = dict(zip(header, line.rstrip('\n').split('\t')))
                frame, rank = int(r['frame']), int(r['rank'])
                frames[frame] = int(r['timestamp_ns'])
                if rank >= 0:
                    rows[(frame, int(r['pass']))][rank] = r
                    ranks = max(ranks, rank + 1)
        n = len(frames)
        shape = (n, 2, ranks)
        self.timestamps = [frames[i] for i in range(n)]
        self.verified = np.zeros(shape, bool)
        self.ransac_inliers = np.zeros(shape)
        self.inliers = np.zeros(shape)
        self.ratio = np.zeros(shape)
        self.significance = np.full(shape, -np.inf)
        self.cells = np.zeros(shape)
        self.correct = np.zeros(shape, bool)  # Found: within 5 cm and 2 degrees.
        self.wrong = np.zeros(shape, bool)  # Another place: beyond 1 m or 10 degrees.
        self.has_gt = gt != '-'
        ground_truth, keyframes = Poses(gt), Poses(anchor)
        for (frame, p), by_rank in rows.items():
            truth = self.truth(ground_truth, keyframes, frames[frame]) if self.has_gt else None
            for rank, r in by_rank.items():
                i = (frame, p - 1, rank)
                self.verified[i] = r['verified'] == '1' and int(r['matches']) >= MIN_MATCHES
                self.ransac_inliers[i] = float(r['ransac_inliers'])
                self.inliers[i] = float(r['inliers'])
                self.ratio[i] = float(r['inlier_ratio'])
                self.significance[i] = float(r['significance'])
                self.cells[i] = float(r['inlier_cells'])
                if truth is not None:
                    R = quat_to_matrix(*(float(r[k]) for k in ('qw', 'qx', 'qy', 'qz')))
                    t = np.array([float(r[k]) for k in ('tx', 'ty', 'tz')])
                    position_error = np.linalg.norm(t - truth[1])
                    cos = (np.trace(truth[0].T @ R) - 1) / 2
                    angle = math.degrees(math.acos(max(-1.0, min(1.0, cos))))
                    self.correct[i] = (position_error <= MAX_POSITION_ERROR_M and
                                       angle <= MAX_ROTATION_ERROR_DEG)
                    self.wrong[i] = position_error > WRONG_POSITION_M or angle > WRONG_ROTATION_DEG

    @staticmethod
    def truth(ground_truth, keyframes, t_ns):
        """map_from_cam of the frame at t_ns: the ground truth itself when the map frame is its
        frame (`keyframes` empty: a generated map), else the ground truth's motion from the map
        keyframe nearest in time applied to that keyframe's pose in the map. A relocalization is
        judged against the map as it is: a map's own drift against the ground truth (KITTI 01's,
        26 cm at the median) is the mapping's error, not the relocalization's."""
        world_from_cam = ground_truth.at(t_ns)
        if world_from_cam is None or not keyframes:
            return world_from_cam
        keyframe_ns = keyframes.nearest_stamp(t_ns)
        map_from_keyframe = keyframes.poses[keyframe_ns]
        world_from_keyframe = ground_truth.at(keyframe_ns)
        if world_from_keyframe is None:
            return None
        # keyframe_from_cam = inv(world_from_keyframe) * world_from_cam
        R_kc = world_from_keyframe[0].T @ world_from_cam[0]
        t_kc = world_from_keyframe[0].T @ (world_from_cam[1] - world_from_keyframe[1])
        return (map_from_keyframe[0] @ R_kc, map_from_keyframe[0] @ t_kc + map_from_keyframe[1])
    def replay(self, rule):
        """(taken, found, wrong) per frame under `rule`; a frame without ground truth is found
        when taken."""
        g, m, r, sig, c, strong_cells = rule
        accepted = (self.verified & (self.ransac_inliers >= g) & (self.inliers >= m) &
                    (self.ratio >= r) & (self.significance >= sig) & (self.cells >= c))
        ranks = accepted.shape[2]
        strong = accepted & (self.inliers >= STRONG_INLIERS) & (self.cells >= strong_cells)
        # Ranks after the first strong accepted candidate are never verified.
        first_strong = np.where(strong.any(axis=2), strong.argmax(axis=2), ranks - 1)
        seen = np.arange(ranks)[None, None, :] <= first_strong[:, :, None]
        usable = accepted & seen
        score = np.where(usable, self.inliers, -1)
        best = score.argmax(axis=2)  # The first of equals, as the relocalizer keeps it.
        found_in_pass = usable.any(axis=2)
        use_pass = np.where(found_in_pass[:, 0], 0, 1)
        frames = np.arange(accepted.shape[0])
        taken = found_in_pass[frames, use_pass]
        chosen = (frames, use_pass, best[frames, use_pass])
        if self.kind == 'negative':
            return taken, np.zeros_like(taken), taken
        if not self.has_gt:
            return taken, taken, np.zeros_like(taken)
        return taken, self.correct[chosen] & taken, self.wrong[chosen] & taken


class Totals:
    """A rule's outcome over all jobs: positives found and off, false positives."""

    def __init__(self, jobs, rule):
        self.per_job = []
        self.found = self.off = self.frames = self.negatives = self.false_positives = 0
        for job in jobs:
            taken, found, wrong = job.replay(rule)
            t, f, w = int(taken.sum()), int(found.sum()), int(wrong.sum())
            self.per_job.append((job, len(taken), t, f, w))
            self.false_positives += w
            if job.kind == 'negative':
                self.negatives += len(taken)
            else:
                self.frames += len(taken)
                self.found += f
                self.off += t - f - w

    def recall(self):
        return f'{100 * self.found / self.frames:.1f}%'


GRID = {
    'RANSAC inliers': [6, 10, 15],
    'verified inliers': [6, 10, 15, 20, 25, 30, 40, 50, 60],
    'inlier ratio': [0.0, 0.2, 0.3, 0.4, 0.5],
    'significance': [0, 5, 10, 15, 20, 25, 30, 35, 40, 50, 60, 80],
    'cells': [0, 6, 12, 18],
    'strong cells': [0, 24, 36],
}


def describe(rule):
    g, m, r, s, c, strong = rule
    parts = [f'RANSAC inliers >= {g}', f'verified inliers >= {m}']
    if r > 0:
        parts.append(f'ratio >= {r:g}')
    if s > 0:
        parts.append(f'significance >= {s:g}')
    if c > 0:
        parts.append(f'cells >= {c}')
    if strong > 0:
        parts.append(f'early stop only with >= {strong} cells')
    return ', '.join(parts)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('jobs')
    parser.add_argument('--report', required=True, help='the Markdown page')
    parser.add_argument('--commit', default='?')
    args = parser.parse_args()
    with open(args.jobs) as f:
        jobs = [Job(*line.rstrip('\n').split('\t')[:7]) for line in f]
    results = {rule: Totals(jobs, rule) for rule in itertools.product(*GRID.values())}
    chosen, margins = choose(jobs, results)
    write_report(args, jobs, results, chosen, margins)
    now, before = results[chosen], results[PREVIOUS_RULE]
    print(f'chosen: {describe(chosen)}: found {now.found} of {now.frames}, {now.off} off, '
          f'0 false positives; before ({describe(PREVIOUS_RULE)}): found {before.found}, '
          f'{before.off} off, {before.false_positives} false positives')


FIXED = {'RANSAC inliers': 15, 'verified inliers': 30, 'inlier ratio': 0.0, 'cells': 0}


def significance_margins(jobs):
    """The strongest negative candidate's significance (any that RANSAC verified) and the
    weakest of the positive frames' best found candidates."""
    strongest_negative, weakest_positive = 0.0, math.inf
    for job in jobs:
        if job.kind == 'negative' and job.verified.any():
            strongest_negative = max(strongest_negative, job.significance[job.verified].max())
        elif job.kind == 'positive' and job.has_gt:
            best = np.where(job.correct & job.verified, job.significance, -np.inf).max(axis=(1, 2))
            if np.isfinite(best).any():
                weakest_positive = min(weakest_positive, best[np.isfinite(best)].min())
    return strongest_negative, weakest_positive


def choose(jobs, results):
    names = list(GRID)
    strongest_negative, weakest_positive = significance_margins(jobs)
    middle = math.sqrt(max(strongest_negative, 1.0) * weakest_positive)
    significance = max(v for v in GRID['significance'] if v <= middle)
    base = [FIXED.get(name) for name in names]
    base[names.index('significance')] = significance
    candidates = []
    for strong in GRID['strong cells']:
        rule = list(base)
        rule[names.index('strong cells')] = strong
        candidates.append(tuple(rule))
    chosen = min(candidates, key=lambda r: (results[r].false_positives, results[r].off))
    best_found = max(t.found for t in results.values() if t.false_positives == 0)
    if results[chosen].false_positives or results[chosen].found < best_found:
        sys.exit(f'{describe(chosen)}: {results[chosen].false_positives} false positives, '
                 f'{results[chosen].found} found where a rule of the grid finds {best_found}')
    return chosen, (strongest_negative, weakest_positive, middle)


def curve_rows(add, name, values, rule_of, results):
    """A curve's table: recall, poses off and false positives of rule_of(v) for each value v."""
    add(f'| {name} | ' + ' | '.join(f'{v:g}' for v in values) + ' |')
    add('|---|' + '---|' * len(values))
    totals = [results[rule_of(v)] for v in values]
    add('| found | ' + ' | '.join(t.recall() for t in totals) + ' |')
    add('| off | ' + ' | '.join(str(t.off) for t in totals) + ' |')
    add('| false positives | ' + ' | '.join(str(t.false_positives) for t in totals) + ' |')
    add('')


def write_report(args, jobs, results, chosen, margins):
    lines = []
    add = lines.append
    now, before = results[chosen], results[PREVIOUS_RULE]
    add('# Relocalization: the acceptance rule and its curve')
    add('')
    add(f'Generated by `scripts/relocalization-rule.sh` from the runs of commit {args.commit}. Do not')
    add('edit by hand: rerun the script.')
    add('')
    add('Every frame of every recording in `../shared/real` goes alone against a map of another part')
    add('of it, both ways (EuRoC: each half against a map of the other, and each outer third, views')
    add('further apart; KITTI, a drive: the even frames against a map of the odd ones and the')
    add('reverse), and the generated query walks against the')
    add('generated room\'s map: the **positives**. A positive is *found* within 5 cm and 2 degrees of')
    add('its truth, *off* beyond that but within 1 m and 10 degrees, and *wrong* beyond (another')
    add('place). The truth is the ground truth\'s motion from the map keyframe nearest in time, applied')
    add('to that keyframe\'s pose in the map (the generated maps are in the ground truth\'s frame): a')
    add('map\'s own error against its ground truth (KITTI 01: 26 cm at the median, `real-world.md`) is')
    add('not the relocalization\'s. KITTI 00 has no ground truth: a pose taken there counts as found.')
    add('The **negatives** are frames of other places: each recording against the maps of the others')
    add('(the two KITTI snippets excepted: one city), each against the generated room, the generated')
    add('room\'s walk against the map of another generated room (another layout, size and textures;')
    add('another seed of the same room is not one: its walls and boxes stand where the first\'s do,')
    add('and its frames localize at their true poses) and the reverse (the out-of-map walk). A **false')
    add('positive** is any pose taken on a negative, or a wrong pose on a positive.')
    add('')
    add('The evidence is taken once with no rule (`visloc relocalize --map-file --evidence`: both')
    add('feature passes, every candidate verified, RANSAC\'s support lowered to 6 inliers so that the')
    add('wrong places show how far they get); each rule is replayed on it as the relocalizer decides')
    add('(`scripts/relocalization_rule.py`: passes, rank order, the early stop at 80 inliers).')
    add('*Significance* is -log10 of the chance that a wrong pose re-matches as many inliers among its')
    add('putatives (each within the 2 px inlier threshold of its projection with p = (2 / r)^2, r the')
    add('tight re-matching radius), less log10 of the 4 candidates tried. *Cells*: of an 8x6 grid over')
    add('the image, those holding an inlier.')
    add('')
    add(f'The significance threshold sits between the strongest negative, {margins[0]:.1f}, and the')
    add(f'weakest found positive, {margins[1]:.1f}: their geometric mean is {margins[2]:.1f}, and the')
    add('grid\'s largest value at or below it is taken (rounded towards the positives: true fixes')
    add('on frames these splits do not hold are weaker than theirs, as the rule it replaces showed).')
    add('The ratio gate is dropped; RANSAC keeps 15 inliers and the')
    add('verification at least 30, what a session calls a strong fix. The early stop at 80 inliers')
    add('asks for the coverage with the fewest poses off.')
    add('')
    add(f'**Chosen: {describe(chosen)}.** Found {now.found} of {now.frames} positives '
        f'({now.recall()}), {now.off} off, 0 false positives on them and on {now.negatives} negative '
        f'frames. Before ({describe(PREVIOUS_RULE)}): '
        f'found {before.found} ({before.recall()}), {before.off} off, {before.false_positives} '
        f'false positives.')
    add('')
    add('What these frames cannot show: every rule of the grid finds the same real frames (the')
    add('curves below are flat in recall), since the splits of `../shared/real` hold no weak true fix.')
    add('The ones that the ratio gate refused (issue 55: later frames of MH_01, 68-126 verified inliers')
    add('at a ratio under 0.5) are not in it; at 752 px (p = (2 / 9.4)^2 = 0.045) 126 inliers of 300')
    add('putatives score 85, and 68 score 49 of 150 putatives or 39 of 200: at the threshold.')
    add('`RelocalizerTest.AcceptsATrueFixWhoseInlierRatioIsLowButWhoseInliersCannotBeChance` builds')
    add('such a fix (a ratio of 0.4) and checks that the rule takes it and the ratio gate did not.')
    add('What separates the rules here is the negatives: the generated room like the map\'s.')
    add('')
    add('## Per recording')
    add('')
    add('Frames, then taken / found / off / wrong (for a negative, taken is its false positives):')
    add('')
    add('| kind | recording | map | queries | frames | before | chosen |')
    add('|---|---|---|---|---|---|---|')
    for (job, n, t0, f0, w0), (_, _, t1, f1, w1) in zip(before.per_job, now.per_job):
        def cell(t, f, w):
            return f'{t}' if job.kind == 'negative' else f'{t} / {f} / {t - f - w} / {w}'
        add(f'| {job.kind} | {job.recording} | {job.map} | {job.query} | {n} | {cell(t0, f0, w0)} | '
            f'{cell(t1, f1, w1)} |')
    add('')
    add('## The curve')
    add('')
    add('Each threshold swept with the others at the chosen rule\'s values: found over the '
        f'{now.frames} positive frames, poses off, false positives over every frame.')
    add('')
    for index, (name, values) in enumerate(GRID.items()):
        def with_value(v, index=index):
            rule = list(chosen)
            rule[index] = v
            return tuple(rule)
        curve_rows(add, name, values, with_value, results)
    add('The ratio gate alone (RANSAC inliers >= 15, verified inliers >= 40, the others off):')
    add('')
    curve_rows(add, 'inlier ratio', GRID['inlier ratio'], lambda v: (15, 40, v, 0, 0, 0), results)
    add('## What the negatives reach')
    add('')
    add('The strongest candidates of any frame of each negative set whose RANSAC found a pose (any')
    add('pass, any rank; a dash: none did):')
    add('')
    add('| recording | map | frames | max RANSAC inliers | max verified inliers | max significance | '
        'max cells | max ratio |')
    add('|---|---|---|---|---|---|---|---|')
    for job in jobs:
        if job.kind != 'negative':
            continue
        v = job.verified
        def top(a, v=v):
            return f'{a[v].max():.1f}' if v.any() else '-'
        add(f'| {job.recording} | {job.map} | {len(job.timestamps)} | {top(job.ransac_inliers)} | '
            f'{top(job.inliers)} | {top(job.significance)} | {top(job.cells)} | {top(job.ratio)} |')
    add('')
    with open(args.report, 'w') as out:
        out.write('\n'.join(lines))


if __name__ == '__main__':
    main()
