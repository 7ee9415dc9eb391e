#!/usr/bin/env python3
"""The README quotes no figure its docs disagree with.

A README paragraph that links a doc (docs/NAME.md) quotes that doc: every measured figure in it
(a number with a unit of measurement: x, %, ms, s, cm, fps, frames/s, sigma, MiB) must appear in
one of the docs it links, as the same number at the README's precision (221 frames/s quotes a
doc's 221.4; 0.7 cm quotes 0.70 cm). Settings and sizes (px, mm, m, Hz, frame counts)
are not checked: they are inputs, not results. When a doc is regenerated and a figure moves, this
test names the README paragraph to update.

Usage: readme_figures_test.py SOURCE_DIR
"""

import os
import re
import sys

FIGURE = re.compile(r"(?<![\w.])(\d+(?:\.\d+)?)\s*(x|%|ms|s|cm|fps|frames/s|sigma|σ|MiB)(?![\w/])")


def quoted(number, doc_numbers):
    """Whether a doc number, rounded to the README's decimals, is `number`."""
    decimals = len(number.split(".")[1]) if "." in number else 0
    value = float(number)
    return any(abs(round(x, decimals) - value) < 1e-9 for x in doc_numbers)


def main(source):
    readme = open(os.path.join(source, "README.md"), encoding="utf-8").read()
    problems, checked = [], 0
    in_code = False
    paragraphs, current = [], []
    for line in readme.splitlines():
        if line.startswith("```"):
            in_code = not in_code
            continue
        if in_code:
            continue
        if line.strip():
            current.append(line)
        elif current:
            paragraphs.append(" ".join(current))
            current = []
    paragraphs.append(" ".join(current))
    for paragraph in paragraphs:
        docs = sorted(set(re.findall(r"docs/[a-z0-9-]+\.md", paragraph)))
        if not docs:
            continue
        text = ""
        for doc in docs:
            path = os.path.join(source, doc)
            if not os.path.exists(path):
                problems.append(f"README links {doc}, which does not exist")
                continue
            text += open(path, encoding="utf-8").read()
        doc_numbers = [float(n) for n in re.findall(r"(?<![\w.])\d+(?:\.\d+)?", text)]
        for number, unit in FIGURE.findall(paragraph):
            checked += 1
            if not quoted(number, doc_numbers):
                problems.append(f"README quotes {number} {unit}, which {', '.join(docs)} do(es) "
                                f"not say: \"{paragraph[:100]}...\"")
    print(f"{checked} figures in README paragraphs that quote docs/")
    for problem in problems:
        print(f"PROBLEM: {problem}")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1] if len(sys.argv) > 1 else "."))
