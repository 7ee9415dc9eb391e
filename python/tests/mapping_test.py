#!/usr/bin/env python3
"""The Python mapping session against the real visloc-server, directly and through a link proxy
that cuts the link mid-run: the job is resumed and the map is the one an unbroken run makes.

Usage: mapping_test.py VISLOC_SERVER VISLOC_LINK_PROXY VISLOC_CLI LOCALIZATION_DATA
The data folder is the localization test fixture (map_square/, a rendered stereo walk at 5 Hz).
"""

import glob
import json
import os
import subprocess
import sys
import tempfile
import time
import unittest

import cv2

from harness import start
from visloc import MappingError, MappingOptions, MappingSession, stereo_rig_from_yaml
from visloc.v1 import visloc_pb2 as pb

SERVER, PROXY, CLI, DATA = sys.argv[1:5]
del sys.argv[1:5]
RUN = os.path.join(DATA, "map_square")
FRAMES = 30


def keyframes(map_path, out):
    subprocess.run([CLI, "map", "export", map_path, "--keyframes", out], check=True,
                   stdout=subprocess.DEVNULL)
    with open(out) as f:
        return f.read()


class PythonMappingTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.maps = tempfile.mkdtemp(prefix="visloc_py_mapping")
        cls.server, cls.address = start([SERVER, "--maps", cls.maps, "--listen", "127.0.0.1:0"])
        left = sorted(glob.glob(os.path.join(RUN, "mav0/cam0/data/*.png")))[:FRAMES]
        cls.frames = [(int(os.path.basename(p)[:-4]), cv2.imread(p, cv2.IMREAD_GRAYSCALE),
                       cv2.imread(p.replace("cam0", "cam1"), cv2.IMREAD_GRAYSCALE)) for p in left]
        cls.rig = stereo_rig_from_yaml(os.path.join(RUN, "mav0/cam0/sensor.yaml"),
                                       os.path.join(RUN, "mav0/cam1/sensor.yaml"))

    @classmethod
    def tearDownClass(cls):
        cls.server.terminate()
        cls.server.wait()

    def stream(self, address, name, pace_s=0.0, options=None):
        mapping = MappingSession(MappingOptions(server=address, map_name=name, rig=self.rig,
                                                mapping=options or pb.MappingOptions()))
        for timestamp_ns, left, right in self.frames:
            mapping.submit(timestamp_ns, left, right)
            time.sleep(pace_s)
        published = mapping.finish()
        return mapping, published, mapping.answers()

    def test_a_run_becomes_the_map_a_build_here_makes(self):
        mapping, published, answers = self.stream(self.address, "py_hall")
        self.assertEqual(published.map.name, "py_hall")
        self.assertEqual(published.frame_index, FRAMES)
        self.assertEqual(len(answers), FRAMES)
        self.assertTrue(all(a.timestamp_ns == f[0] for (a, _), f in zip(answers, self.frames)))
        self.assertGreater(mapping.job_id, 0)
        here = os.path.join(self.maps, "..", "py_here.db")
        subprocess.run([CLI, "map", "build", "--dataset", RUN, "--frames", f"0:{FRAMES}", "--out",
                        here], check=True, stdout=subprocess.DEVNULL)
        self.assertEqual(keyframes(os.path.join(self.maps, "py_hall.db"), here + ".link.tum"),
                         keyframes(here, here + ".tum"))

    def test_a_known_disparity_correction_is_the_builds_and_the_maps(self):
        known = pb.DisparityCorrection(offset_px=0.05, right_camera_yaw_deg=0.002)
        _, published, _ = self.stream(self.address, "py_rig",
                                      options=pb.MappingOptions(disparity_correction=known))
        self.assertEqual(published.disparity_correction.offset_px, 0.05)
        self.assertAlmostEqual(published.disparity_correction.right_camera_yaw_deg, 0.002,
                               places=12)
        info = json.loads(subprocess.run(
            [CLI, "map", "info", os.path.join(self.maps, "py_rig.db"), "--json"], check=True,
            stdout=subprocess.PIPE).stdout)
        self.assertEqual(info["disparity_correction"]["offset_px"], 0.05)
        self.assertAlmostEqual(info["disparity_correction"]["right_camera_yaw_deg"], 0.002,
                               places=12)

    def test_a_cut_link_is_resumed(self):
        proxy, address = start([PROXY, "--upstream", self.address, "--cut-every-s", "1",
                                "--cut-ms", "1500", "--cuts", "1", "--seconds", "60"])
        try:
            mapping, published, _ = self.stream(address, "py_cut", pace_s=0.1)
        finally:
            proxy.terminate()
            proxy.wait()
        self.assertGreaterEqual(mapping.resumes, 1)
        self.assertEqual(published.frame_index, FRAMES)
        self.assertTrue(os.path.exists(os.path.join(self.maps, "py_cut.db")))

    def test_a_taken_name_is_refused_by_name(self):
        open(os.path.join(self.maps, "taken.db"), "wb").close()
        with self.assertRaisesRegex(MappingError, "a map named 'taken' already exists"):
            MappingSession(MappingOptions(server=self.address, map_name="taken", rig=self.rig))


if __name__ == "__main__":
    unittest.main()
