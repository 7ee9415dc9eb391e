#!/usr/bin/env python3
"""visloc-server --http end to end: real robots (`visloc stream`) on a real server, its /metrics
parsed by the Prometheus client library's own parser (Debian's python3-prometheus-client).

- /healthz and /readyz answer 200 on a serving server;
- the frame counters equal the frames the robots sent, per map, summed over statuses; the
  server-time histogram counts every answered frame; both sessions are counted; the kidnapped
  robot's relocalizations are found; no label carries a robot id;
- a browser's request (Accept-Encoding: gzip, deflate, br) gets the page and a map's view
  gzip-compressed, not Brotli (cpp-httplib's Brotli is its slowest quality: 0.37 s of CPU for a
  small map's view against gzip's 0.02 s), and the view decodes to the JSON sent uncompressed;
- with the server's TLS certificate it serves HTTPS (and no plain HTTP);
- with tokens, /metrics refuses a call without one (401) and answers a robot's token; the probes
  stay open for the orchestrator.

  http_e2e_test.py VISLOC_SERVER VISLOC LOCALIZATION_DATA
"""

import gzip
import http.client
import json
import os
import ssl
import subprocess
import sys
import tempfile
import urllib.error
import urllib.request

from prometheus_client.parser import text_string_to_metric_families

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "support"))
from http_harness import Checks, square_maps, start_server  # noqa: E402

server_bin, visloc_bin, data = sys.argv[1:4]


def get(url, token=None):
    request = urllib.request.Request(url)
    if token:
        request.add_header("Authorization", "Bearer " + token)
    try:
        with urllib.request.urlopen(request, timeout=10) as response:
            return response.status, response.read().decode()
    except urllib.error.HTTPError as e:
        return e.code, e.read().decode()


def get_as_browser(url):
    """(Content-Encoding, body decoded) of a request that accepts what browsers accept."""
    request = urllib.request.Request(url, headers={"Accept-Encoding": "gzip, deflate, br"})
    with urllib.request.urlopen(request, timeout=10) as response:
        encoding = response.headers.get("Content-Encoding", "")
        body = response.read()
    if encoding == "gzip":
        body = gzip.decompress(body)
    return encoding, body.decode() if encoding in ("gzip", "") else ""


def check_compression(check, base):
    page_encoding, page = get_as_browser(base + "/")
    check(page_encoding == "gzip" and "<canvas" in page,
          f"the page as a browser gets it: '{page_encoding}'")
    view_encoding, view = get_as_browser(base + "/api/maps/square/view")
    check(view_encoding == "gzip", f"a map's view as a browser gets it: '{view_encoding}'")
    check(view and json.loads(view) == json.loads(get(base + "/api/maps/square/view")[1]),
          "the gzip-compressed view decodes to the uncompressed one")


def samples(text):
    """(name, labels, value) of every sample, through Prometheus' own parser."""
    return [(s.name, s.labels, s.value) for family in text_string_to_metric_families(text)
            for s in family.samples]


def stream(address, robot, sequence, frames):
    result = subprocess.run(
        [visloc_bin, "stream", "--server", address, "--map", "square", "--robot-id", robot,
         "--dataset", os.path.join(data, sequence), "--frames", str(frames), "--rate", "0",
         "--json"], capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout.strip().splitlines()[-1])


def thread_nices(pid):
    """(the process's main thread's nice, every thread's nice) from /proc."""
    def nice(stat_path):
        with open(stat_path) as f:
            # Fields after the command's closing parenthesis start at field 3; nice is field 19.
            return int(f.read().rsplit(")", 1)[1].split()[16])
    tasks = os.listdir(f"/proc/{pid}/task")
    return nice(f"/proc/{pid}/stat"), [nice(f"/proc/{pid}/task/{t}/stat") for t in tasks]


def main():
    check = Checks()
    with tempfile.TemporaryDirectory() as tmp:
        maps = square_maps(tmp, data)
        server, grpc_address, http_address = start_server(server_bin, maps)
        try:
            base = "http://" + http_address
            check(get(base + "/healthz") == (200, "ok\n"), "/healthz")
            check(get(base + "/readyz")[0] == 200, "/readyz on a serving server")
            check_compression(check, base)
            # The container healthcheck's way: visloc health --http asks /readyz.
            health = subprocess.run([visloc_bin, "health", "--http", http_address, "--json"],
                                    capture_output=True, text=True, timeout=30)
            check(health.returncode == 0 and '"ready":true' in health.stdout,
                  f"visloc health --http: {health.returncode} {health.stdout} {health.stderr}")
            kidnap = stream(grpc_address, "rover-kidnap", "kidnap", 120)
            walk = stream(grpc_address, "rover-walk", "query_square", 60)
            sent = kidnap["frames"] + walk["frames"]
            status, text = get(base + "/metrics")
            check(status == 200, f"/metrics answered {status}")
            found = samples(text)
            frames = sum(v for n, l, v in found if n == "visloc_frames_total" and l["map"] == "square")
            check(frames == sent, f"visloc_frames_total {frames}, the robots sent {sent}")
            by_status = {l["status"]: v for n, l, v in found if n == "visloc_frames_total"}
            check(by_status.get("tracking", 0) > 100, f"tracked frames {by_status}")
            check(by_status.get("lost", 0) > 0, f"the kidnapped robot's lost frames {by_status}")
            answered = sum(v for k, v in by_status.items() if k != "skipped")
            count = [v for n, l, v in found if n == "visloc_frame_server_seconds_count"]
            check(count == [answered], f"histogram count {count}, answered {answered}")
            started = [v for n, l, v in found if n == "visloc_sessions_started_total"]
            check(started == [2], f"sessions started {started}")
            relocalized = {l["result"]: v for n, l, v in found
                           if n == "visloc_relocalizations_total"}
            check(relocalized.get("found", 0) >= 1, f"relocalizations {relocalized}")
            check(("visloc_maps_loaded", {}, 1.0) in found, "one map loaded")
            localize_rpcs = [v for n, l, v in found if n == "visloc_rpcs_total" and
                             l == {"method": "/visloc.v1.Localization/Localize", "code": "OK"}]
            check(localize_rpcs == [2], f"Localize RPCs that ended OK: {localize_rpcs}")
            check(not any("rover" in value for _, l, _ in found for value in l.values()),
                  "a label carries a robot id")
            check("/tmp" not in text and tmp not in text, "a server path in /metrics")
            # The threads that served these requests run below the localization workers.
            base, niced = thread_nices(server.pid)
            wanted = min(19, base + 10)
            check(niced.count(wanted) >= 1 and niced.count(base) >= 2,
                  f"HTTP threads at nice {wanted}, the rest at {base}: {sorted(niced)}")
        finally:
            server.terminate()
            server.wait(timeout=30)

        # TLS: the server's certificate serves HTTPS too; plain HTTP is not answered.
        key, cert = os.path.join(tmp, "key.pem"), os.path.join(tmp, "cert.pem")
        subprocess.run(["/usr/bin/openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes",
                        "-keyout", key, "-out", cert, "-days", "1", "-subj", "/CN=localhost",
                        "-addext", "subjectAltName=IP:127.0.0.1,DNS:localhost"],
                       check=True, capture_output=True)
        server, _, http_address = start_server(server_bin, maps, ["--tls-cert", cert, "--tls-key", key])
        try:
            context = ssl.create_default_context(cafile=cert)
            with urllib.request.urlopen("https://" + http_address + "/healthz", timeout=10,
                                        context=context) as response:
                check(response.status == 200, "/healthz over HTTPS")
            try:
                get("http://" + http_address + "/healthz")
                check(False, "plain HTTP answered on a TLS server")
            except (urllib.error.URLError, ConnectionError, http.client.HTTPException):
                pass
        finally:
            server.terminate()
            server.wait(timeout=30)

        tokens = os.path.join(tmp, "tokens")
        with open(tokens, "w") as f:
            f.write("robot-token-0123456789 localize\n")
        server, _, http_address = start_server(server_bin, maps, ["--tokens", tokens])
        try:
            base = "http://" + http_address
            status, body = get(base + "/metrics")
            check(status == 401 and "bearer token" in body, f"/metrics without a token: {status}")
            check(get(base + "/metrics", "robot-token-0123456789")[0] == 200, "/metrics, token")
            check(get(base + "/metrics", "wrong-token-000000000")[0] == 401, "/metrics, bad token")
            check(get(base + "/healthz")[0] == 200 and get(base + "/readyz")[0] == 200,
                  "the probes need no token")
        finally:
            server.terminate()
            server.wait(timeout=30)

    gone = subprocess.run([visloc_bin, "health", "--http", http_address], capture_output=True,
                          text=True, timeout=30)
    check(gone.returncode == 1 and "no answer" in gone.stderr,
          f"visloc health --http on a stopped server: {gone.returncode} {gone.stderr}")
    if not check.failures:
        print("http endpoint: probes, HTTPS, metrics equal to the frames sent, tokens")
    return check.report()


if __name__ == "__main__":
    sys.exit(main())
