"""What the Python client's tests share: starting the real binaries."""

import subprocess


def start(argv):
    """A child that prints 'listening on ADDRESS'; returns (process, address)."""
    process = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    line = process.stdout.readline()
    if not line.startswith("listening on "):
        process.kill()
        raise RuntimeError(f"{argv[0]} did not start: {line!r}")
    return process, line.split()[-1]
