#!/usr/bin/env python3
"""visloc.camera_from_yaml: the files visloc writes and real EuRoC calibrations read as the C++
library reads them, and problems named by file and key.

Usage: camera_test.py VISLOC_BINARY [REAL_DATA_DIR]  (PYTHONPATH holds the package)
"""

import os
import subprocess
import sys
import tempfile
import unittest

from visloc import camera_from_yaml
from visloc.v1 import visloc_pb2 as pb

VISLOC = sys.argv[1] if len(sys.argv) > 1 else "visloc"
REAL = sys.argv[2] if len(sys.argv) > 2 else ""


class CameraFromYamlTest(unittest.TestCase):
    def setUp(self):
        self.dir = tempfile.TemporaryDirectory(prefix="visloc-camera-test")

    def tearDown(self):
        self.dir.cleanup()

    def write(self, name, text):
        path = os.path.join(self.dir.name, name)
        with open(path, "w") as f:
            f.write(text)
        return path

    def error(self, name, text=None):
        path = self.write(name, text) if text is not None else os.path.join(self.dir.name, name)
        with self.assertRaises(ValueError) as raised:
            camera_from_yaml(path)
        return str(raised.exception)

    def test_what_visloc_sim_writes(self):
        for lens, model in (("pinhole", pb.RADIAL_TANGENTIAL), ("fisheye", pb.EQUIDISTANT)):
            out = os.path.join(self.dir.name, lens)
            subprocess.run([VISLOC, "sim", "--out", out, "--sequence", "map_square",
                            "--frames", "1", "--distortion", "--lens", lens], check=True,
                           stdout=subprocess.DEVNULL)
            camera = camera_from_yaml(os.path.join(out, "map_square/mav0/cam0/sensor.yaml"))
            self.assertEqual((camera.width, camera.height), (320, 240))
            self.assertEqual(camera.lens_model, model)
            self.assertEqual(len(camera.distortion), 4)
            self.assertNotEqual(list(camera.distortion), [0, 0, 0, 0])

    def test_a_real_euroc_calibration(self):
        path = os.path.join(REAL, "euroc_mh01_moving/mav0/cam0/sensor.yaml")
        if not os.path.isfile(path):
            self.skipTest(f"no real recordings at {REAL or '(not given)'}")
        camera = camera_from_yaml(path)
        self.assertEqual((camera.width, camera.height), (752, 480))
        self.assertEqual((camera.fx, camera.fy, camera.cx, camera.cy),
                         (458.654, 457.296, 367.215, 248.375))
        self.assertEqual(camera.lens_model, pb.RADIAL_TANGENTIAL)
        self.assertAlmostEqual(camera.distortion[0], -0.28340811)

    def test_problems_name_the_file_and_the_key(self):
        good = "camera_model: pinhole\nresolution: [320, 240]\nintrinsics: [160, 160, 159.5, 119.5]\n"
        self.assertEqual(len(camera_from_yaml(self.write("good.yaml", good)).distortion), 0)
        self.assertIn("absent.yaml: no such file", self.error("absent.yaml"))
        self.assertIn("no_model.yaml: missing 'camera_model'",
                      self.error("no_model.yaml", "resolution: [320, 240]\n"))
        self.assertIn("unsupported camera_model 'omni'", self.error("omni.yaml", "camera_model: omni\n"))
        self.assertIn("short.yaml: 'intrinsics' must be a list of 4 numbers",
                      self.error("short.yaml", good.replace(", 119.5]", "]")))
        self.assertIn("'resolution' has a non-number",
                      self.error("words.yaml", good.replace("[320,", "[wide,")))
        self.assertIn("unsupported distortion_model 'kb8'",
                      self.error("kb8.yaml", good + "distortion_model: kb8\n"))
        self.assertIn("'distortion_coefficients' must be a list of 4 numbers",
                      self.error("three.yaml", good + "distortion_model: equidistant\n"
                                 "distortion_coefficients: [0, 0, 0]\n"))
        self.assertIn("garbage.yaml: ", self.error("garbage.yaml", "[: {\n"))


if __name__ == "__main__":
    unittest.main(argv=sys.argv[:1], verbosity=2)
