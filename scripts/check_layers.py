#!/usr/bin/env python3
"""The layering check: the include graph and the CMake dependencies against the module table of
docs/architecture.md, which is their source of truth.

Each table row names its CMake target(s) (`visloc::NAME`, or a binary) and, in its last column,
the visloc targets it may use, in backticks (other text there, such as OpenCV, is external and
not checked). A target may use what it declares and, through them, everything below. The check
fails on:
  - an include of a header owned by a target that is neither the includer's own nor below it
    (an upward or undeclared edge; a cycle is one too);
  - a CMake dependency (DEPS, PRIVATE_DEPS) on a visloc target the table does not allow;
  - a target in CMake that the table does not list, or a table dependency on an unknown target.
Sources are owned by the target whose SRCS list them; a header by the target of its .cc, else by
the first target declared in its folder. Tests, benchmarks, fuzzers and examples are not
checked: they may reach across layers to test them.

  scripts/check_layers.py [--root DIR]   exit 0: clean; 1: violations, each on a line.
"""

import argparse
import os
import re
import sys

EXEMPT = re.compile(r"(_test\.cc|_benchmark\.cc|_fuzzer\.cc|_test_writer\.h)$")
EXEMPT_DIRS = ("tests/", "fuzz/", "examples/", "build", "out/", "python/", "docs/", ".")
# Binaries and the folders whose sources they are (besides what their libraries own).
BINARIES = {
    "visloc": ("client/",),
    "visloc-server": ("server/main.cc",),
    "visloc_ros_node": ("ros/node/visloc_ros_node.cc", "ros/node/mapping_node.cc",
                        "ros/node/mapping_node.h", "ros/node/ros_camera_info.h"),
}


def read(path):
    with open(path, encoding="utf-8") as f:
        return f.read()


def parse_table(root):
    """target -> set of declared visloc dependencies (short names), from the module table."""
    text = read(os.path.join(root, "docs/architecture.md"))
    table = text.split("## Modules", 1)[1].split("\n\n", 2)[1]
    declared = {}
    for line in table.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) < 4 or set(cells[0]) <= set("-: "):
            continue
        targets = re.findall(r"`visloc::([a-z0-9_]+)`", cells[1])
        targets += [b for b in BINARIES if f"`{b}` (binary" in cells[1]]
        deps = set(re.findall(r"`([a-z0-9_]+)`", cells[-1]))
        for target in targets:
            declared.setdefault(target, set()).update(deps)
    return declared


def parse_cmake(root):
    """target -> (folder, sources, visloc deps) from the CMakeLists.txt files."""
    targets = {}
    order = []
    for folder, _, files in os.walk(root):
        rel = os.path.relpath(folder, root)
        if rel.startswith(("build", "out", ".git", "python")) or "CMakeLists.txt" not in files:
            continue
        text = read(os.path.join(folder, "CMakeLists.txt"))
        text = re.sub(r"#[^\n]*", "", text)
        for m in re.finditer(r"visloc_add_library\(\s*([a-z0-9_]+)(.*?)\)", text, re.S):
            name, body = m.group(1), m.group(2)
            srcs = re.search(r"SRCS(.*?)(DEPS|PRIVATE_DEPS|$)", body, re.S).group(1).split()
            deps = set(re.findall(r"visloc::([a-z0-9_]+)", body))
            prefix = "" if rel == "." else rel + "/"
            targets[name] = (prefix, [prefix + s for s in srcs], deps)
            order.append(name)
        # The client library is a plain add_library (it is installed on its own).
        for m in re.finditer(r"add_library\(visloc_client STATIC([^)]*)\)", text):
            prefix = rel + "/"
            link = re.search(r"target_link_libraries\(visloc_client(.*?)\)", text, re.S)
            deps = set(re.findall(r"visloc::([a-z0-9_]+)", link.group(1))) if link else set()
            targets["client"] = (prefix + "lib/", [prefix + s for s in m.group(1).split()], deps)
            order.append("client")
        for m in re.finditer(r"target_link_libraries\((visloc|visloc-server|visloc_ros_node)\s(.*?)\)",
                             text, re.S):
            folder_deps = targets.setdefault(m.group(1), (rel + "/", [], set()))[2]
            folder_deps.update(re.findall(r"visloc::([a-z0-9_]+)", m.group(2)))
    return targets, order


def owners(root, targets, order):
    """file -> owning target, for every checked source and header."""
    owner = {}
    for name in order:
        for src in targets[name][1]:
            owner[src] = name
            owner[src[:-3] + ".h"] = name
    # The client library's public headers.
    for folder, _, files in os.walk(os.path.join(root, "client/include")):
        for f in files:
            owner[os.path.relpath(os.path.join(folder, f), root)] = "client"
    # Header-only files: the first target declared in their folder.
    first_in = {}
    for name in order:
        first_in.setdefault(targets[name][0], name)
    for binary, paths in BINARIES.items():
        for where in paths:
            if where.endswith((".cc", ".h")):
                owner[where] = binary
    for folder, _, files in os.walk(root):
        rel = os.path.relpath(folder, root) + "/"
        for f in files:
            path = rel + f if rel != "./" else f
            if path in owner or not f.endswith((".h", ".cc")):
                continue
            if path.startswith("client/") and not path.startswith("client/lib/"):
                owner[path] = "visloc"
            elif rel in first_in:
                owner[path] = first_in[rel]
    return owner


def closure(declared, target, seen=None):
    seen = set() if seen is None else seen
    for dep in declared.get(target, ()):
        if dep not in seen:
            seen.add(dep)
            closure(declared, dep, seen)
    return seen


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--root", default=os.path.join(os.path.dirname(__file__), ".."))
    root = os.path.abspath(parser.parse_args().root)
    declared = parse_table(root)
    targets, order = parse_cmake(root)
    owner = owners(root, targets, order)
    problems = []
    for name in sorted(set(targets) - set(declared)):
        problems.append(f"CMake target {name} is not in the module table of docs/architecture.md")
    for name, deps in sorted(declared.items()):
        for dep in sorted(deps - set(declared)):
            problems.append(f"docs/architecture.md: {name} depends on unknown target {dep}")
        if name in closure(declared, name):
            problems.append(f"docs/architecture.md: {name} depends on itself (a cycle)")
    for name, (_, _, deps) in sorted(targets.items()):
        allowed = closure(declared, name)
        for dep in sorted(deps - allowed - {name}):
            problems.append(f"CMake: {name} links {dep}, which the module table does not allow")
    for path, target in sorted(owner.items()):
        full = os.path.join(root, path)
        if EXEMPT.search(path) or path.startswith(EXEMPT_DIRS) or not os.path.exists(full):
            continue
        allowed = closure(declared, target) | {target}
        for number, line in enumerate(read(full).splitlines(), 1):
            m = re.match(r'\s*#\s*include\s+"([^"]+)"', line)
            if not m:
                continue
            included = m.group(1)
            if included.startswith("visloc/client/"):
                included = "client/include/" + included
            used = owner.get(included)
            if used is None or used in allowed:
                continue
            kind = "upward" if target in closure(declared, used) else "undeclared"
            problems.append(f"{path}:{number}: {kind} include of {m.group(1)} ({target} -> {used})")
    for problem in problems:
        print(problem)
    if problems:
        print(f"check-layers: {len(problems)} problem(s); the module table of "
              "docs/architecture.md is the source of truth", file=sys.stderr)
        return 1
    print(f"check-layers: {len(owner)} files of {len(targets)} targets follow the module table")
    return 0


if __name__ == "__main__":
    sys.exit(main())
