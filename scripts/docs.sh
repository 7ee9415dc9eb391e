#!/usr/bin/env bash
# Regenerates every generated doc from one commit, in one run: docs/benchmarks.md,
# real-cameras.md, real-world.md (against --baseline REV when given), relocalization.md,
# robot-link.md, maps.md, big-maps.md and ros.md (when ROS 1 is installed). Each names the commit in its header; this
# script refuses a tree with uncommitted changes, so that commit is what ran. Then it checks that
# the README quotes no figure the docs now disagree with (tests/docs/readme_figures_test.py) and
# names the paragraphs to update.
#
# Usage: scripts/docs.sh [--baseline REV]   (about 70 minutes on 2 cores from scratch; each script
# keeps its runs in out/NAME and reuses them; logs in out/docs. Run it on a quiet machine: the
# timings are ratios, but a busy machine still skews them. Each script reads HEAD when it starts:
# do not commit while this runs, or the docs name different commits)
set -euo pipefail
cd "$(dirname "$0")/.."
baseline=()
if [[ ${1:-} == --baseline ]]; then
  baseline=(--baseline "$2")
  shift 2
fi
work=out/docs
if [[ -n $(git status --porcelain --untracked-files=no) ]]; then
  echo "scripts/docs.sh: commit first: each doc names the commit it ran" >&2
  exit 1
fi
commit=$(git rev-parse --short HEAD)
bash scripts/build.sh
mkdir -p "$work"
run() {
  local name=$1
  shift
  echo "== $name (commit $commit)"
  local start=$SECONDS
  bash "scripts/$name.sh" "$@" > "$work/$name.log" 2>&1 || {
    echo "scripts/$name.sh failed: see $work/$name.log" >&2; tail -20 "$work/$name.log" >&2; exit 1; }
  echo "   $((SECONDS - start)) s"
}
run benchmarks
run robot-link  # Reuses the benchmarks' maps and sequences.
run real-cameras
run real-world "${baseline[@]}"
run relocalization-rule
run maps
run big-maps
if command -v roscore > /dev/null; then run ros; fi
/usr/bin/python3 tests/docs/readme_figures_test.py .
echo "docs regenerated from commit $commit"
