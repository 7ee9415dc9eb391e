#!/usr/bin/env bash
# The layering check (CI runs it through CTest as check_layers): every include and every CMake
# dependency against the module table of docs/architecture.md. Exit 1 names each violation.
set -euo pipefail
exec /usr/bin/python3 "$(dirname "$0")/check_layers.py" --root "$(cd "$(dirname "$0")/.." && pwd)" "$@"
