#!/usr/bin/env python3
"""scripts/check_layers.py holds: the tree as it is passes, and a copy of it with planted
violations fails, naming each one: an upward include of a header-only file (the include paths
would let it compile), an include of a module not declared below, and a CMake dependency the
module table does not allow.

  check_layers_test.py REPO_ROOT
"""

import os
import shutil
import subprocess
import sys
import tempfile


def run(root):
    script = os.path.join(root, "scripts", "check_layers.py")
    return subprocess.run(["/usr/bin/python3", script, "--root", root], capture_output=True,
                          text=True)


def plant(path, after, text):
    with open(path, encoding="utf-8") as f:
        content = f.read()
    assert after in content, (path, after)
    with open(path, "w", encoding="utf-8") as f:
        f.write(content.replace(after, after + text, 1))


def main():
    root = os.path.abspath(sys.argv[1])
    clean = run(root)
    if clean.returncode != 0:
        print("the tree fails its own layering check:\n" + clean.stdout + clean.stderr)
        return 1
    with tempfile.TemporaryDirectory() as tmp:
        copy = os.path.join(tmp, "visloc")
        listed = []
        for folder, dirs, files in os.walk(root):
            rel = os.path.relpath(folder, root)
            dirs[:] = [d for d in dirs if not (rel == "." and d in ("build", "out", ".git"))
                       and not d.startswith("build")]
            listed += [os.path.normpath(os.path.join(rel, f)) for f in files]
        for rel in listed:
            if rel.endswith((".h", ".cc", ".txt", ".md", ".py")):
                os.makedirs(os.path.dirname(os.path.join(copy, rel)), exist_ok=True)
                shutil.copy(os.path.join(root, rel), os.path.join(copy, rel))
        plant(os.path.join(copy, "core/map/map.h"), "#pragma once\n",
              '#include "server/work_permits.h"\n')
        plant(os.path.join(copy, "mapstore/map_upload.cc"), '#include "mapstore/map_upload.h"\n',
              '#include "mapping/map_merge.h"\n')
        plant(os.path.join(copy, "core/localization/CMakeLists.txt"), "DEPS visloc::map",
              " visloc::mapstore")
        planted = run(copy)
        expected = [
            "core/map/map.h:2: upward include of server/work_permits.h (map -> server_lib)",
            "mapstore/map_upload.cc:2: undeclared include of mapping/map_merge.h",
            "CMake: localization links mapstore",
        ]
        missing = [e for e in expected if e not in planted.stdout]
        if planted.returncode != 1 or missing:
            print(f"planted violations: exit {planted.returncode}, missing {missing}\n" +
                  planted.stdout + planted.stderr)
            return 1
    print("check_layers: clean tree passes; 3 planted violations found")
    return 0


if __name__ == "__main__":
    sys.exit(main())
