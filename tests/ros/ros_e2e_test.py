#!/usr/bin/python3
"""visloc's ROS 1 side end to end, with ROS's own tools as the independent side.

1. Bag import: the generated square (stereo, the right camera as PNG CompressedImage with every
   50th image missing, odometry) is written into a ROS 1 bag by python3-rosbag, imported with
   `visloc dataset import`, mapped with `visloc map build`, and the query sequence is localized
   in that map against ground truth.
2. The node: roscore, the real visloc-server serving the imported map, visloc_ros_node started by
   roslaunch with its launch file, and `rosbag play`:
   - query_square (raw images, odometry that comes 20 ms late every other frame, IMU with its TF):
     published poses against ground truth, every image sent with the odometry of its own stamp
     and tracked throughout, the TF map -> odom closing the chain with the odometry (REP 105),
     diagnostics, the relocalize service;
   - query_square again, the server killed mid-run and restarted: the node reconnects and poses
     resume;
   - kidnap (JPEG CompressedImage, no odometry, TF map -> camera): no pose while the camera is
     covered, a status that says lost, poses again after relocalization;
   - a rig (the front camera and a rear one, both JPEG CompressedImage, placed by /tf_static):
     the pose kept while the front camera is covered;
   Poses are compared with the ground truth in the map's site frame (REP 105's z-up map).
   - mapping mode: the generated square's stereo bag through visloc_mapping.launch to the
     server's mapper, ended by the node's finish_map service, against the same frames mapped here;
   - with --real, the real EuRoC snippet: its bag (camera_info with OpenCV's rectification, as
     ROS's stereo calibration writes it) imported and mapped, and its left camera through the node.
Prints the figures docs/ros.md quotes; --report FILE writes them as JSON.
Usage: ros_e2e_test.py --visloc BIN --server BIN --ros-ws DIR --data DIR --work DIR [--report F]
"""
import argparse
import bisect
import csv
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
FAILURES = []


def check(condition, message):
    print(("ok: " if condition else "FAIL: ") + message, flush=True)
    if not condition:
        FAILURES.append(message)


def run(cmd, **kw):
    print("$ " + " ".join(cmd), flush=True)
    result = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            timeout=kw.pop("timeout", 600), **kw)
    if result.returncode != 0:
        sys.exit("command failed (%d): %s\n%s%s" % (result.returncode, " ".join(cmd),
                                                     result.stdout, result.stderr))
    return result.stdout


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_port(port, seconds):
    deadline = time.time() + seconds
    while time.time() < deadline:
        with socket.socket() as s:
            if s.connect_ex(("127.0.0.1", port)) == 0:
                return True
        time.sleep(0.1)
    return False


def quat_to_matrix(qx, qy, qz, qw):
    x, y, z, w = qx, qy, qz, qw
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def pose_matrix(t, q):
    m = np.eye(4)
    m[:3, :3] = quat_to_matrix(*q)
    m[:3, 3] = t
    return m


def read_tum(path):
    poses = {}
    with open(path) as f:
        for line in f:
            if line.startswith("#") or not line.strip():
                continue
            v = [float(x) for x in line.split()]
            poses[int(round(v[0] * 1e9))] = pose_matrix(v[1:4], v[4:8])
    return poses


def site_ground_truth(visloc, map_db, path):
    """A sequence's ground truth (map frame) in the map's site frame, as the node publishes its
    poses (REP 105's map, z up): turned by the map's site_from_map (`map info`); unchanged for a
    map that records no up."""
    info = json.loads(run([visloc, "map", "info", map_db, "--json"]))
    s = info.get("site", {}).get("site_from_map")
    site_from_map = np.eye(4) if s is None else pose_matrix(
        [s["tx"], s["ty"], s["tz"]], [s["qx"], s["qy"], s["qz"], s["qw"]])
    return {t: site_from_map @ m for t, m in read_tum(path).items()}


def read_odometry(path):
    poses = {}
    with open(path) as f:
        for row in csv.reader(f):
            if row and not row[0].startswith("#"):
                v = [float(x) for x in row[1:8]]
                poses[int(row[0])] = pose_matrix(v[0:3], v[3:7])
    return poses


def nearest(poses, stamp_ns, tolerance_ns=1000000):
    keys = sorted(poses)
    i = bisect.bisect_left(keys, stamp_ns)
    for j in (i - 1, i):
        if 0 <= j < len(keys) and abs(keys[j] - stamp_ns) <= tolerance_ns:
            return poses[keys[j]]
    return None


def part_import(a, work):
    data = a.data
    bag = os.path.join(work, "map.bag")
    run(["/usr/bin/python3", os.path.join(HERE, "euroc_to_rosbag.py"), os.path.join(data, "map_square"),
         bag, "--right-compressed", "--drop-right", "50", "--odometry"])
    out = os.path.join(work, "imported")
    start = time.monotonic()
    report = json.loads(run([a.visloc, "dataset", "import", "--rosbag", bag, "--left", "/cam0/image_raw",
                             "--right", "/cam1/image_raw/compressed", "--odometry", "/odom",
                             "--out", out, "--json"]))
    import_s = time.monotonic() - start
    frames = len(os.listdir(os.path.join(data, "map_square", "mav0", "cam0", "data")))
    check(report["frames"] == frames - frames // 50,
          "import: %d of %d frames paired (every 50th right image missing)" % (report["frames"], frames))
    check(report["unpaired_left"] == frames // 50, "import: %d unpaired left images reported" % report["unpaired_left"])
    check(report["camera_source"] == "camera_info" and abs(report["baseline_m"] - 0.144) < 1e-9,
          "import: rig from camera_info, baseline %.4f m" % report["baseline_m"])
    check(report["odometry_poses"] == frames, "import: %d odometry poses" % report["odometry_poses"])
    map_db = os.path.join(work, "maps", "square_ros.db")
    os.makedirs(os.path.dirname(map_db), exist_ok=True)
    run([a.visloc, "map", "build", "--dataset", out, "--out", map_db, "--name", "square_ros"], timeout=900)
    trajectory = os.path.join(work, "localize.tum")
    run([a.visloc, "localize", "--map", map_db, "--dataset", os.path.join(data, "query_square"),
         "--trajectory", trajectory])
    ev = json.loads(run([a.visloc, "eval", "--gt", os.path.join(data, "query_square", "groundtruth_map.tum"),
                         "--est", trajectory, "--json"]))
    ev["import_s"] = import_s
    ev["imported_frames"] = report["frames"]
    ev["bag_frames"] = frames
    ev["bag_mb"] = os.path.getsize(bag) / 1e6
    return map_db, ev


class Listener:
    """Records what the node publishes, with wall-clock receipt times."""

    def __init__(self, image_topic, image_type):
        import rospy
        from diagnostic_msgs.msg import DiagnosticArray
        from geometry_msgs.msg import PoseWithCovarianceStamped
        from std_msgs.msg import String
        from tf2_msgs.msg import TFMessage
        self.lock = threading.Lock()
        self.poses, self.tf, self.statuses, self.images = {}, [], [], {}
        self.pose_times = {}
        self.diagnostics = None
        self.subs = [
            rospy.Subscriber("/visloc/pose", PoseWithCovarianceStamped, self.on_pose, queue_size=500),
            rospy.Subscriber("/tf", TFMessage, self.on_tf, queue_size=500),
            rospy.Subscriber("/visloc/status", String, self.on_status, queue_size=100),
            rospy.Subscriber("/diagnostics", DiagnosticArray, self.on_diag, queue_size=10),
            rospy.Subscriber(image_topic, image_type, self.on_image, queue_size=500),
        ]

    def close(self):
        for s in self.subs:
            s.unregister()

    def on_pose(self, m):
        p, q = m.pose.pose.position, m.pose.pose.orientation
        with self.lock:
            stamp = m.header.stamp.to_nsec()
            self.poses[stamp] = (m.header.frame_id, pose_matrix([p.x, p.y, p.z], [q.x, q.y, q.z, q.w]),
                                 list(m.pose.covariance))
            self.pose_times[stamp] = time.monotonic()

    def on_tf(self, m):
        with self.lock:
            for t in m.transforms:
                r, q = t.transform.translation, t.transform.rotation
                self.tf.append((t.header.frame_id, t.child_frame_id, t.header.stamp.to_nsec(),
                                pose_matrix([r.x, r.y, r.z], [q.x, q.y, q.z, q.w])))

    def on_status(self, m):
        with self.lock:
            self.statuses.append(m.data)

    def on_diag(self, m):
        with self.lock:
            for s in m.status:
                if s.name.startswith("visloc"):
                    self.diagnostics = (s.level, {kv.key: kv.value for kv in s.values})

    def on_image(self, m):
        with self.lock:
            self.images[m.header.stamp.to_nsec()] = time.monotonic()


class RosWorld:
    def __init__(self, a, work, map_db):
        self.a, self.work = a, work
        self.env = dict(os.environ)
        master = free_port()
        self.env.update(ROS_MASTER_URI="http://127.0.0.1:%d" % master, ROS_IP="127.0.0.1",
                        ROS_HOME=os.path.join(work, "ros_home"),
                        CMAKE_PREFIX_PATH=a.ros_ws + ":" + self.env.get("CMAKE_PREFIX_PATH", ""),
                        ROS_PACKAGE_PATH=os.path.join(a.ros_ws, "share"))
        os.environ.update(self.env)
        self.procs = []
        self.logs = []
        self.start("roscore", ["roscore", "-p", str(master)])
        check(wait_port(master, 30), "roscore listening on %d" % master)
        self.server_port = free_port()
        self.maps = os.path.dirname(map_db)
        self.server = self.start_server()
        import rospy
        rospy.init_node("visloc_ros_test", anonymous=True, disable_signals=True)

    def start_server(self):
        server = self.start("server", [self.a.server, "--maps", self.maps, "--listen",
                                       "127.0.0.1:%d" % self.server_port])
        check(wait_port(self.server_port, 30), "visloc-server listening on %d" % self.server_port)
        return server

    def start(self, name, cmd):
        log = open(os.path.join(self.work, name + ".log"), "w")
        self.logs.append(log)
        p = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, env=self.env,
                             start_new_session=True)
        self.procs.append((name, p))
        return p

    def stop(self, p, seconds=15):
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGINT)
            try:
                p.wait(seconds)
            except subprocess.TimeoutExpired:
                os.killpg(p.pid, signal.SIGKILL)
                p.wait()
        return p.returncode

    def close(self):
        import rospy
        rospy.signal_shutdown("test over")
        for name, p in reversed(self.procs):
            self.stop(p)
        for log in self.logs:
            log.close()


def wait_for(predicate, seconds):
    deadline = time.time() + seconds
    while time.time() < deadline:
        if predicate():
            return True
        time.sleep(0.1)
    return False


def play(world, name, launch_args, bag, image_topic, image_type, during=None):
    """Starts the node with roslaunch, plays the bag (calling `during()` meanwhile, if given),
    returns what was published."""
    import rosgraph
    listener = Listener(image_topic, image_type)
    args = ["map:=square_ros"] if not any(x.startswith("map:=") for x in launch_args) else []
    node = world.start("node_" + name, ["roslaunch", "visloc_ros", "visloc.launch",
                                        "server:=127.0.0.1:%d" % world.server_port, "camera:=/cam0"]
                       + args + launch_args)
    master = rosgraph.Master("/visloc_ros_test")
    check(wait_for(lambda: any(t == "/visloc/pose" for t, _ in master.getPublishedTopics("/")), 60),
          "%s: the node advertises /visloc/pose" % name)
    # The node subscribes before rosbag plays (rosbag play does not wait for subscribers).
    check(wait_for(lambda: any(t == "/cam0/camera_info" for t, _ in master.getSystemState()[1]), 30),
          "%s: the node subscribes to /cam0/camera_info" % name)
    start = time.monotonic()
    player = subprocess.Popen(["rosbag", "play", "-q", "--delay=0.5", "-r", str(world.a.rate), bag],
                              env=world.env, stdout=subprocess.DEVNULL)
    if during:
        during()
    check(player.wait(120) == 0, "%s: rosbag play finished" % name)
    played_s = time.monotonic() - start
    wait_for(lambda: listener.diagnostics is not None and
             int(listener.diagnostics[1].get("frames_answered", 0)) +
             int(listener.diagnostics[1].get("frames_dropped", 0)) >=
             int(listener.diagnostics[1].get("images_received", 1)) - 1, 10)
    time.sleep(1.5)  # One more diagnostics period.
    return listener, node, played_s


def dropped_frames(listener):
    """Frames the node's link dropped or saw undelivered or late (reported, never silent): on a
    loaded machine the engine may fall behind the camera, and the node drops rather than lags."""
    values = listener.diagnostics[1] if listener.diagnostics else {}
    return int(values.get("frames_dropped", 0)) + int(values.get("frames_late", 0))


def rate_hz(receipt_times):
    """Poses a second, from the first to the last one received."""
    t = sorted(receipt_times.values())
    return (len(t) - 1) / (t[-1] - t[0]) if len(t) > 1 and t[-1] > t[0] else 0.0


def errors_cm(poses, gt):
    errs = []
    for stamp, (_, m, _) in poses.items():
        g = nearest(gt, stamp)
        if g is not None:
            errs.append(np.linalg.norm(m[:3, 3] - g[:3, 3]) * 100)
    return np.array(errs)


def part_real_import(a, work, figures):
    """The real EuRoC snippet through a bag whose camera_info carries OpenCV's rectification,
    as ROS's stereo calibration writes it: the rig must come back and map as the EuRoC folder."""
    bag = os.path.join(work, "euroc_real.bag")
    run(["/usr/bin/python3", os.path.join(HERE, "euroc_to_rosbag.py"), a.real, bag])
    out = os.path.join(work, "euroc_real")
    report = json.loads(run([a.visloc, "dataset", "import", "--rosbag", bag, "--left", "/cam0/image_raw",
                             "--right", "/cam1/image_raw", "--out", out, "--json"]))
    check(report["frames"] == 95 and abs(report["baseline_m"] - 0.1101) < 5e-4,
          "real EuRoC bag: %d frames, baseline %.4f m" % (report["frames"], report["baseline_m"]))
    map_db = os.path.join(work, "maps", "euroc_ros.db")
    build = json.loads(run([a.visloc, "map", "build", "--dataset", out, "--out", map_db, "--name",
                            "euroc_ros", "--json"], timeout=900))
    points = build["points"]
    check(points is not None and points >= 500, "real EuRoC bag: map of %s points" % points)
    figures["real_import"] = {"frames": report["frames"], "baseline_m": report["baseline_m"], "points": points}


def part_real_node(world, a, work, figures):
    """The real EuRoC left camera through the node: every frame posed, a still camera's jitter."""
    from sensor_msgs.msg import Image
    bag = os.path.join(work, "euroc_real_mono.bag")
    run(["/usr/bin/python3", os.path.join(HERE, "euroc_to_rosbag.py"), a.real, bag, "--mono"])
    listener, node, played_s = play(world, "euroc", ["map:=euroc_ros"], bag, "/cam0/image_raw", Image)
    positions = np.array([m[:3, 3] for _, m, _ in listener.poses.values()])
    spread_mm = float(np.max(np.linalg.norm(positions - positions.mean(axis=0), axis=1)) * 1000) if len(positions) else -1
    dropped = dropped_frames(listener)
    check(len(listener.poses) + dropped >= 93 and len(listener.poses) >= 76 and 0 <= spread_mm < 5.0,
          "real EuRoC through the node: %d poses for 95 frames (%d dropped), positions within %.2f mm of their mean"
          % (len(listener.poses), dropped, spread_mm))
    latencies = [1000 * (listener.pose_times[s] - listener.images[s])
                 for s in listener.pose_times if s in listener.images]
    figures["real_node"] = {"frames": 95, "poses": len(listener.poses), "spread_mm": spread_mm,
                            "pose_rate_hz": rate_hz(listener.pose_times),
                            "camera_rate_hz": 20.0,
                            "latency_ms_p50": float(np.percentile(latencies, 50)) if latencies else None,
                            "latency_ms_p95": float(np.percentile(latencies, 95)) if latencies else None}
    world.stop(node)
    listener.close()


def part_node(a, work, map_db, figures):
    data = a.data
    query_bag = os.path.join(work, "query.bag")
    # Every other odometry message comes 20 ms after its image: the node must wait for it rather
    # than send the image with the frame before's odometry (a held fix, then relocalized).
    run(["/usr/bin/python3", os.path.join(HERE, "euroc_to_rosbag.py"), os.path.join(data, "query_square"),
         query_bag, "--mono", "--odometry", "--odometry-lag-ms", "20", "--imu"])
    kidnap_bag = os.path.join(work, "kidnap.bag")
    run(["/usr/bin/python3", os.path.join(HERE, "euroc_to_rosbag.py"), os.path.join(data, "kidnap"),
         kidnap_bag, "--mono", "--left-compressed"])
    from sensor_msgs.msg import CompressedImage, Image
    world = RosWorld(a, work, map_db)
    try:
        # Query: raw images, odometry, TF map -> odom.
        gt = site_ground_truth(a.visloc, map_db, os.path.join(data, "query_square", "groundtruth_map.tum"))
        odom = read_odometry(os.path.join(data, "query_square", "mav0", "odometry0", "data.csv"))
        listener, node, played_s = play(world, "query", ["use_odometry:=true", "use_imu:=true",
                                                         "sensor_wait_s:=%g" % a.sensor_wait_s],
                                        query_bag, "/cam0/image_raw", Image)
        frames = len(gt)
        errs = errors_cm(listener.poses, gt)
        dropped = dropped_frames(listener)
        check(len(listener.poses) + dropped >= frames - 2 and len(listener.poses) >= 0.8 * frames,
              "query: %d poses for %d frames (%d dropped by the node's link)" % (len(listener.poses), frames, dropped))
        check(len(errs) > 0 and np.median(errs) < 1.0 and errs.max() < 3.0,
              "query: error against ground truth median %.3f cm, max %.3f cm" % (np.median(errs), errs.max()))
        check(all(f == "map" for f, _, _ in listener.poses.values()), "query: poses in the map frame")
        # REP 105's map has z up: the level walk's camera looks level, its image's down along -z.
        tilts = [np.degrees(np.arccos(np.clip(-m[2, 1], -1, 1))) for _, m, _ in listener.poses.values()]
        check(len(tilts) > 0 and np.median(tilts) < 5.0,
              "query: published z up (the camera's down %.2f deg from -z, median)" % np.median(tilts))
        cov_ok = all(c[0] > 0 and c[7] > 0 and c[14] > 0 and c[21] > 0 for _, _, c in listener.poses.values())
        check(cov_ok, "query: every pose carries a positive covariance")
        chain = []
        for parent, child, stamp, map_from_odom in listener.tf:
            if parent == "map" and child == "odom" and stamp in listener.poses:
                o = nearest(odom, stamp)
                if o is not None:
                    chain.append(np.linalg.norm((map_from_odom @ o)[:3, 3] - listener.poses[stamp][1][:3, 3]))
        # Every pose has its map -> odom. Counted against the poses, not the frames: a frame the
        # node's link dropped under load (reported, checked above) has neither.
        with_odometry = sum(1 for stamp in listener.poses if nearest(odom, stamp) is not None)
        check(len(chain) >= with_odometry - 2 and len(chain) >= 0.8 * frames and max(chain) < 1e-6,
              "query: %d TF map -> odom for %d poses, closing map -> odom -> camera on the pose within %.1e m"
              % (len(chain), with_odometry, max(chain) if chain else -1))
        check(not any(child == "cam0" for _, child, _, _ in listener.tf), "query: no map -> camera TF with odometry")
        level, values = listener.diagnostics or (-1, {})
        check(level == 0 and values.get("status") == "STATUS_TRACKING" and int(values.get("inliers", 0)) > 100,
              "query: diagnostics OK, %s, %s inliers" % (values.get("status"), values.get("inliers")))
        # Relocalized once, at the start, then tracking: no fix held for a stale prediction.
        check(listener.statuses.count("STATUS_RELOCALIZED") == 1 and
              listener.statuses[-1] == "STATUS_TRACKING",
              "query: relocalized once, then tracking (%s)" % " -> ".join(listener.statuses))
        check(int(values.get("frames_without_odometry", -1)) == 0,
              "query: %s frames sent without the odometry of their stamp"
              % values.get("frames_without_odometry"))
        # 200 Hz gyro over 8 s, its frame from /tf_static: every sample after the first image sent.
        check(int(values.get("imu_samples_sent", 0)) > 1500,
              "query: %s IMU samples sent with the frames" % values.get("imu_samples_sent"))
        # Latency apart for the frames whose odometry came with the image and those whose odometry
        # came 20 ms later (every other one, in the order of the odometry's rows): these wait for it.
        odom_stamps = sorted(odom)
        latencies, latencies_odometry_late = [], []
        for s in listener.pose_times:
            if s in listener.images:
                row = bisect.bisect_left(odom_stamps, s)
                (latencies_odometry_late if row % 2 else latencies).append(
                    1000 * (listener.pose_times[s] - listener.images[s]))
        figures["query"] = {
            "frames": frames, "poses": len(listener.poses), "median_error_cm": float(np.median(errs)),
            "max_error_cm": float(errs.max()), "pose_rate_hz": rate_hz(listener.pose_times),
            "camera_rate_hz": 15.0,
            "latency_ms_p50": float(np.percentile(latencies, 50)) if latencies else None,
            "latency_ms_p95": float(np.percentile(latencies, 95)) if latencies else None,
            "latency_odometry_late_ms_p50":
                float(np.percentile(latencies_odometry_late, 50)) if latencies_odometry_late else None,
        }
        print("figures: %s" % json.dumps(figures["query"]), flush=True)
        import rospy
        from std_srvs.srv import Trigger
        rospy.wait_for_service("/visloc/relocalize", 10)
        answer = rospy.ServiceProxy("/visloc/relocalize", Trigger)()
        last = gt[max(gt)]
        check(answer.success and "inliers" in answer.message, "relocalize service: %s" % answer.message)
        world.stop(node)
        listener.close()

        # The server dies mid-run and comes back: the node's session reconnects and resumes.
        restart = {}

        def kill_and_restart():
            time.sleep(3.0)
            os.killpg(world.server.pid, signal.SIGKILL)
            world.server.wait()
            restart["down"] = time.monotonic()
            time.sleep(1.0)
            world.server = world.start_server()
            restart["up"] = time.monotonic()

        listener, node, played_s = play(world, "reconnect",
                                        ["use_odometry:=true", "sensor_wait_s:=%g" % a.sensor_wait_s],
                                        query_bag, "/cam0/image_raw", Image, during=kill_and_restart)
        after = {s: p for s, p in listener.poses.items() if listener.pose_times[s] > restart["up"]}
        errs = errors_cm(after, gt)
        first = min(listener.pose_times[s] for s in after) - restart["up"] if after else -1
        check(any(st.startswith("link reconnecting") for st in listener.statuses),
              "reconnect: status reports the link reconnecting")
        check(len(after) >= 30 and np.median(errs) < 1.0 and errs.max() < 3.0,
              "reconnect: %d poses after the server came back (first after %.2f s), median error %.3f cm"
              % (len(after), first, np.median(errs) if len(errs) else -1))
        figures["reconnect"] = {"poses_after": len(after), "first_pose_after_s": first,
                                "median_error_cm": float(np.median(errs)) if len(errs) else None}
        world.stop(node)
        listener.close()

        # Kidnap: compressed images, no odometry (TF map -> camera); covered frames get no pose.
        meta = json.load(open(os.path.join(data, "kidnap", "sequence.json")))
        gt = site_ground_truth(a.visloc, map_db, os.path.join(data, "kidnap", "groundtruth_map.tum"))
        stamps = sorted(gt)
        covered = {stamps[i] for i in meta["covered_frames"] if i < len(stamps)}
        listener, node, played_s = play(world, "kidnap", ["transport:=compressed"], kidnap_bag,
                                        "/cam0/image_raw/compressed", CompressedImage)
        # The stamps as the node published them (the ground truth's TUM stamps are rounded).
        during = [s for s in covered if nearest(listener.poses, s) is not None]
        check(len(during) == 0, "kidnap: %d poses published while the camera was covered (%d frames)"
              % (len(during), len(covered)))
        check("STATUS_LOST" in listener.statuses, "kidnap: status says lost (%s)" % " -> ".join(listener.statuses))
        after = [s for s in listener.poses if s > max(covered)]
        errs = errors_cm(listener.poses, gt)
        frames_after = len([s for s in stamps if s > max(covered)])
        dropped = dropped_frames(listener)
        check(len(after) + dropped >= 0.9 * frames_after and len(after) >= 0.7 * frames_after,
              "kidnap: %d poses for the %d frames after the kidnapping (%d frames dropped in all)"
              % (len(after), frames_after, dropped))
        check(len(errs) > 0 and np.median(errs) < 1.0 and errs.max() < 5.0,
              "kidnap: every published pose near ground truth (median %.3f cm, max %.3f cm)"
              % (np.median(errs), errs.max()))
        check(any(p == "map" and c == "cam0" for p, c, _, _ in listener.tf), "kidnap: TF map -> cam0 without odometry")
        figures["kidnap"] = {"frames": len(stamps), "covered": len(covered), "poses": len(listener.poses),
                             "poses_while_covered": len(during), "median_error_cm": float(np.median(errs))}
        world.stop(node)
        listener.close()

        # A rig: the same walk with a rear camera (/cam2, placed by /tf_static): the robot keeps
        # its pose while the front camera is covered.
        walk = os.path.join(data, "front-back", "kidnap")
        rig_bag = os.path.join(work, "rig.bag")
        # Every camera's images compressed (JPEG), as a robot short of bandwidth sends them.
        run(["/usr/bin/python3", os.path.join(HERE, "euroc_to_rosbag.py"), walk, rig_bag, "--mono",
             "--rig-camera", "cam2", "--left-compressed", "--rig-compressed"])
        meta = json.load(open(os.path.join(walk, "sequence.json")))
        gt = site_ground_truth(a.visloc, map_db, os.path.join(walk, "groundtruth_map.tum"))
        stamps = sorted(gt)
        covered = {stamps[i] for i in meta["covered_frames"] if i < len(stamps)}
        listener, node, played_s = play(world, "rig", ["rig_cameras:=/cam2", "transport:=compressed"],
                                        rig_bag, "/cam0/image_raw/compressed", CompressedImage)
        during = [s for s in covered if nearest(listener.poses, s) is not None]
        errs = errors_cm(listener.poses, gt)
        dropped = dropped_frames(listener)
        check(len(during) + dropped >= len(covered) - 1 and len(during) >= 0.7 * len(covered),
              "rig: %d poses while the front camera was covered (%d frames, %d dropped in all; %s)"
              % (len(during), len(covered), dropped, " -> ".join(listener.statuses)))
        check(len(errs) > 0 and np.median(errs) < 1.0 and errs.max() < 3.0,
              "rig: every published pose near ground truth (median %.3f cm, max %.3f cm)"
              % (np.median(errs) if len(errs) else -1, errs.max() if len(errs) else -1))
        figures["rig"] = {"frames": len(stamps), "covered": len(covered), "poses": len(listener.poses),
                          "poses_while_covered": len(during),
                          "median_error_cm": float(np.median(errs)) if len(errs) else None}
        world.stop(node)
        listener.close()
        part_mapping(world, a, work, figures)
        if a.real:
            part_real_node(world, a, work, figures)
    finally:
        world.close()


def part_mapping(world, a, work, figures):
    """The node in mapping mode: a stereo bag of the generated square through it to the server's
    mapper, the run ended by the node's finish_map service; the published map against the same
    frames mapped here."""
    import rosgraph
    import rospy
    from std_srvs.srv import Trigger
    bag = os.path.join(work, "mapping.bag")
    run(["/usr/bin/python3", os.path.join(HERE, "euroc_to_rosbag.py"),
         os.path.join(a.data, "map_square"), bag])
    node = world.start("node_mapping", ["roslaunch", "visloc_ros", "visloc_mapping.launch",
                                        "server:=127.0.0.1:%d" % world.server_port,
                                        "map:=square_over_ros"])
    master = rosgraph.Master("/visloc_ros_test")
    check(wait_for(lambda: all(any(t == topic for t, _ in master.getSystemState()[1])
                               for topic in ("/cam0/image_raw", "/cam1/image_raw",
                                             "/cam1/camera_info")), 60),
          "mapping: the node subscribes to both cameras")
    player = subprocess.Popen(["rosbag", "play", "-q", "--delay=0.5", "-r", str(a.rate), "-u", "12",
                               bag], env=world.env, stdout=subprocess.DEVNULL)
    check(player.wait(120) == 0, "mapping: rosbag play finished")
    rospy.wait_for_service("/visloc_mapper/finish_map", 30)
    answer = rospy.ServiceProxy("/visloc_mapper/finish_map", Trigger)()
    check(answer.success and "published 'square_over_ros'" in answer.message,
          "mapping: finish_map says %r" % answer.message)
    frames = int(answer.message.split(": ")[1].split(" frames")[0]) if answer.success else 0
    check(frames >= 50, "mapping: %d stereo frames mapped (12 s of a 5 Hz camera)" % frames)
    published = os.path.join(world.maps, "square_over_ros.db")
    here = os.path.join(work, "mapping_here.db")
    run([a.visloc, "map", "build", "--dataset", os.path.join(a.data, "map_square"), "--frames",
         "0:%d" % frames, "--out", here])
    link = read_tum_positions(a.visloc, published, os.path.join(work, "mapping_link.tum"))
    local = read_tum_positions(a.visloc, here, os.path.join(work, "mapping_here.tum"))
    worst_mm = max((np.linalg.norm(link[t] - local[t]) * 1000 for t in local if t in link),
                   default=float("inf"))
    check(len(link) == len(local) and worst_mm < 1.0,
          "mapping: %d keyframes over ROS and the link, %d built here, %.4f mm apart at most"
          % (len(link), len(local), worst_mm))
    figures["mapping"] = {"frames": frames, "keyframes": len(link), "worst_keyframe_mm": worst_mm}
    world.stop(node)


def read_tum_positions(visloc, map_db, out):
    """timestamp_ns -> keyframe position (m) of a map file."""
    # In the map frame (the first camera's): each map's level frame is its own estimate of up.
    run([visloc, "map", "export", map_db, "--keyframes", out, "--frame", "map"])
    return {t: m[:3, 3] for t, m in read_tum(out).items()}


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--visloc", required=True)
    p.add_argument("--server", required=True)
    p.add_argument("--ros-ws", required=True)
    p.add_argument("--data", required=True)
    p.add_argument("--work", required=True)
    p.add_argument("--report")
    p.add_argument("--real", help="the real EuRoC snippet (skipped when absent)")
    p.add_argument("--rate", type=float, default=1.0,
                   help="rosbag play's rate factor (sanitizer builds run slower than the camera)")
    p.add_argument("--sensor-wait-s", type=float, default=0.1,
                   help="the node's wait for an image's odometry (wall time; longer under sanitizers)")
    a = p.parse_args()
    if a.real and not os.path.isdir(a.real):
        print("no real recording at %s: its checks are skipped" % a.real)
        a.real = None
    shutil.rmtree(a.work, ignore_errors=True)
    os.makedirs(a.work)
    figures = {}
    map_db, ev = part_import(a, a.work)
    t = ev["ate"]["translation_m"]
    figures["import"] = {"localize_median_cm": t["median"] * 100, "localized": ev["matched_poses"],
                         "frames": ev["gt_poses"], "import_s": ev["import_s"],
                         "imported_frames": ev["imported_frames"], "bag_frames": ev["bag_frames"],
                         "bag_mb": ev["bag_mb"]}
    check(ev["coverage"] == 1 and t["median"] * 100 < 1.0,
          "localize in the imported map: %d of %d frames, median %.3f cm"
          % (ev["matched_poses"], ev["gt_poses"], t["median"] * 100))
    if a.real:
        part_real_import(a, a.work, figures)
    part_node(a, a.work, map_db, figures)
    if a.report:
        with open(a.report, "w") as f:
            json.dump(figures, f, indent=1)
    if FAILURES:
        sys.exit("%d checks failed:\n  %s" % (len(FAILURES), "\n  ".join(FAILURES)))
    print("all ROS checks passed")


if __name__ == "__main__":
    main()
