#!/usr/bin/env python3
"""The operator's page open in headless Chromium for a soak (scripts/soak-held.sh): loaded at the
start, left open, sampled every minute, and checked live at the end. Prints one JSON object.

Usage: soak_page.py URL DURATION_S ROBOTS READY_FILE

READY_FILE is written once the page is loaded and live, before the robots start: the browser's
own start (seconds of several processes' CPU, on the server's cores here) is not the server's
load. The run's DURATION_S counts from then.
"""
import json
import os
import subprocess
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests",
                                "support"))
from http_harness import browser  # noqa: E402


def sample(driver):
    return driver.execute_script(
        "return {link: document.getElementById('link').textContent,"
        " robots: document.querySelectorAll('.robot').length,"
        " load: document.getElementById('load').textContent,"
        " view: document.getElementById('viewinfo').textContent,"
        " since_event_s: (Date.now() - state.lastEvent) / 1000};")


def browser_cpu_s():
    """The CPU time (s) of every Chromium process so far."""
    out = subprocess.run(["ps", "-C", "chromium,chrome", "-o", "times="], capture_output=True,
                         text=True).stdout
    return sum(int(v) for v in out.split())


def main():
    url, duration_s, robots, ready_file = (sys.argv[1], float(sys.argv[2]), int(sys.argv[3]),
                                           sys.argv[4])
    driver = browser()
    samples = []
    try:
        driver.get(url)
        deadline = time.monotonic() + 60
        while sample(driver)["link"] != "live" and time.monotonic() < deadline:
            time.sleep(0.2)
        time.sleep(2)  # The map's view and overlay drawn.
        with open(ready_file, "w") as f:
            f.write("ready\n")
        start = time.monotonic()
        # Sampled each minute, and last a few seconds before the robots end.
        next_sample = start + 60
        while time.monotonic() < start + duration_s - 5:
            time.sleep(max(0.0, min(next_sample, start + duration_s - 5) - time.monotonic()))
            samples.append(dict(sample(driver), t_s=round(time.monotonic() - start)))
            next_sample += 60
        errors = [e["message"] for e in driver.get_log("browser") if e["level"] == "SEVERE"]
        cores = browser_cpu_s() / max(1.0, time.monotonic() - start)
    finally:
        driver.quit()
    last = samples[-1] if samples else {}
    live = (last.get("link") == "live" and last.get("robots") == robots
            and last.get("since_event_s", 99) < 2 and "keyframes" in last.get("view", ""))
    print(json.dumps({"live_at_end": live, "console_errors": errors, "browser_cores": cores,
                      "samples": samples}))


if __name__ == "__main__":
    main()
