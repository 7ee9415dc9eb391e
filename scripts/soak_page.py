#!/usr/bin/env python3
"""The operator's page open in headless Chromium for a soak (scripts/soak-held.sh): loaded at the
start, left open, sampled every minute, and checked live at the end. Prints one JSON object.

Usage: soak_page.py URL DURATION_S ROBOTS
"""
import json
import shutil
import sys
import time

from selenium import webdriver
from selenium.webdriver.chrome.service import Service


def browser():
    options = webdriver.ChromeOptions()
    options.binary_location = shutil.which("chromium")
    for argument in ["--headless=new", "--no-sandbox", "--disable-gpu", "--window-size=1400,900",
                     "--disable-dev-shm-usage"]:
        options.add_argument(argument)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    return webdriver.Chrome(service=Service("/usr/bin/chromedriver"), options=options)


def sample(driver):
    return driver.execute_script(
        "return {link: document.getElementById('link').textContent,"
        " robots: document.querySelectorAll('.robot').length,"
        " load: document.getElementById('load').textContent,"
        " view: document.getElementById('viewinfo').textContent,"
        " since_event_s: (Date.now() - state.lastEvent) / 1000};")


def main():
    url, duration_s, robots = sys.argv[1], float(sys.argv[2]), int(sys.argv[3])
    driver = browser()
    samples = []
    try:
        driver.get(url)
        start = time.monotonic()
        # Sampled each minute, and last a few seconds before the robots end.
        next_sample = start + 60
        while time.monotonic() < start + duration_s - 5:
            time.sleep(max(0.0, min(next_sample, start + duration_s - 5) - time.monotonic()))
            samples.append(dict(sample(driver), t_s=round(time.monotonic() - start)))
            next_sample += 60
        errors = [e["message"] for e in driver.get_log("browser") if e["level"] == "SEVERE"]
    finally:
        driver.quit()
    last = samples[-1] if samples else {}
    live = (last.get("link") == "live" and last.get("robots") == robots
            and last.get("since_event_s", 99) < 2 and "keyframes" in last.get("view", ""))
    print(json.dumps({"live_at_end": live, "console_errors": errors, "samples": samples}))


if __name__ == "__main__":
    main()
