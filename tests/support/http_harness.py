"""What the HTTP-side tests share (http_e2e_test.py, operator_page_test.py, and
scripts/soak_page.py): a failures list, a maps folder holding the fixture's map as "square", a
real visloc-server with --http on free loopback ports, and headless Chromium."""

import os
import shutil
import subprocess


class Checks:
    """Collects failed checks, so a test reports all of them, not the first."""

    def __init__(self):
        self.failures = []

    def __call__(self, condition, what):
        if not condition:
            self.failures.append(what)

    def report(self):
        for failure in self.failures:
            print("FAILED:", failure)
        return 1 if self.failures else 0


def square_maps(tmp, data):
    """TMP/maps with the localization fixture's map as "square"."""
    maps = os.path.join(tmp, "maps")
    os.makedirs(maps)
    shutil.copy(os.path.join(data, "map.db"), os.path.join(maps, "square.db"))
    return maps


def start_server(server_bin, maps, extra=()):
    """(process, gRPC address, HTTP address) of a visloc-server on free loopback ports.
    Admission by load is off unless `extra` sets it, as in tests/support/process.cc: under a
    sanitizer a robot that reconnects beside others would be refused for a sanitizer's load."""
    if "--admit-busy" not in extra:
        extra = [*extra, "--admit-busy", "0"]
    process = subprocess.Popen(
        [server_bin, "--maps", maps, "--listen", "127.0.0.1:0", "--http", "127.0.0.1:0", *extra],
        stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    grpc_address = process.stdout.readline().split()[-1]
    http_line = process.stdout.readline()
    assert http_line.startswith("http on "), http_line
    return process, grpc_address, http_line.split()[-1]


def browser():
    """Headless Chromium through chromedriver (Debian's), its console log kept."""
    from selenium import webdriver  # Only the page tests need selenium.
    from selenium.webdriver.chrome.service import Service
    options = webdriver.ChromeOptions()
    options.binary_location = shutil.which("chromium")
    for argument in ["--headless=new", "--no-sandbox", "--disable-gpu", "--window-size=1400,900",
                     "--disable-dev-shm-usage"]:
        options.add_argument(argument)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    return webdriver.Chrome(service=Service("/usr/bin/chromedriver"), options=options)
