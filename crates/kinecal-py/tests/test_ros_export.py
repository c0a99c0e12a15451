"""`kinecal export ros` read by ROS's own tools: the xacro it writes, expanded by the `xacro`
package from PyPI with no argument, is a URDF whose forward kinematics (computed here, from the
URDF's origins and axes) behind the measurement frame's static transform equals `kinecal fk` of
the calibrated robot, to 1e-9 m and 1e-9 rad; the YAML files are read by PyYAML (as xacro and
the launch file read them), the hash is recomputed, the static transforms equal the robot
file's session frames, and the launch file, run against stand-ins of `launch` and `launch_ros`,
starts one static_transform_publisher per frame with the YAML's values.

On the UR10 (../shared/data's URDF), the Franka Panda (a prismatic finger), random 6-axis arms
and the two-arm tree of examples/trees. Run by `bash crates/kinecal-py/test.sh -k ros`.
"""

import csv
import hashlib
import importlib.util
import math
import os
import random
import struct
import subprocess
import sys
import types
import xml.etree.ElementTree as ET

import numpy as np
import pytest
import yaml
from conftest import ROOT, SKIP_REASON

SHARED = os.environ.get("KINECAL_SHARED_DATA") or os.path.join(ROOT, "..", "shared", "data")

# The target of the issue: the xacro's forward kinematics equals kinecal's to 1e-9 m. Both sides
# are double precision products of a few transforms (|t| < 3 m): they agree to ~1e-15 m.
TOLERANCE = 1e-9

# Session frames added to the calibrated robot (the global frame in each session's
# measurement frame: x, y, z in metres, alpha, beta, gamma in radians).
SESSIONS = {
    "A": (0.01, 0.02, -0.03, 0.001, 0.002, -0.003),
    "tracker 2": (-1.5, 3.0, 0.2, 0.1, 1.2, -2.9),
}


def xacro_command():
    """The `xacro` entry point of this Python environment."""
    exe = os.path.join(os.path.dirname(sys.executable), "xacro")
    if not os.path.exists(exe):
        pytest.fail("the xacro package is not installed (test.sh installs it)")
    return exe


def rot_x(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def rot_y(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def rot_z(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def homogeneous(r, t):
    m = np.eye(4)
    m[:3, :3] = r
    m[:3, 3] = t
    return m


def axis_angle(axis, q):
    """Rodrigues' rotation about the unit `axis` by `q`."""
    k = np.array(axis) / np.linalg.norm(axis)
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(q) * kx + (1 - math.cos(q)) * kx @ kx


def numbers(text, n):
    v = [float(x) for x in (text or " ".join(["0"] * n)).split()]
    assert len(v) == n
    return v


def urdf_joints(text):
    """The URDF's joints: name -> (type, parent, child, xyz, rpy, axis)."""
    root = ET.fromstring(text)
    out = {}
    for j in root.findall("joint"):
        origin = j.find("origin")
        axis = j.find("axis")
        out[j.get("name")] = (
            j.get("type"),
            j.find("parent").get("link"),
            j.find("child").get("link"),
            numbers(origin.get("xyz") if origin is not None else None, 3),
            numbers(origin.get("rpy") if origin is not None else None, 3),
            numbers(axis.get("xyz") if axis is not None else "1 0 0", 3),
        )
    return out


def urdf_fk(joints, base, tip, q):
    """The tip's frame in the base: `origin * motion(axis, q[name])` along the chain."""
    by_child = {j[2]: (name, j) for name, j in joints.items()}
    chain = []
    at = tip
    while at != base:
        name, j = by_child[at]
        chain.append((name, j))
        at = j[1]
    t = np.eye(4)
    for name, (kind, _, _, xyz, rpy, axis) in reversed(chain):
        t = t @ homogeneous(rot_z(rpy[2]) @ rot_y(rpy[1]) @ rot_x(rpy[0]), xyz)
        if kind in ("revolute", "continuous"):
            t = t @ homogeneous(axis_angle(axis, q[name]), np.zeros(3))
        elif kind == "prismatic":
            t = t @ homogeneous(np.eye(3), np.array(axis) / np.linalg.norm(axis) * q[name])
    return t


def transform(t):
    """A static transform of the YAML as a 4x4 matrix (child in parent)."""
    qx, qy, qz, qw = t["qx"], t["qy"], t["qz"], t["qw"]
    assert abs(qx * qx + qy * qy + qz * qz + qw * qw - 1) < 1e-15
    r = np.array([
        [1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qz * qw), 2 * (qx * qz + qy * qw)],
        [2 * (qx * qy + qz * qw), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qx * qw)],
        [2 * (qx * qz - qy * qw), 2 * (qy * qz + qx * qw), 1 - 2 * (qx * qx + qy * qy)],
    ])
    return homogeneous(r, [t["x"], t["y"], t["z"]])


def zyx(a, b, c):
    """kinecal's link and pose angles: Rz(alpha) Ry(beta) Rx(gamma)."""
    return rot_z(a) @ rot_y(b) @ rot_x(c)


def random_arm_urdf(seed):
    """A 6-axis arm of random origins and axes, a fixed tool link."""
    rng = random.Random(seed)
    parts = ['<?xml version="1.0"?>\n<robot name="random_arm">\n  <link name="base_link"/>\n']
    parent = "base_link"
    for k in range(1, 8):
        child = f"link{k}" if k <= 6 else "tool0"
        kind = "revolute" if k <= 6 else "fixed"
        v = [rng.uniform(-0.4, 0.4) for _ in range(8)]
        parts.append(
            f'  <link name="{child}"/>\n  <joint name="j{k}" type="{kind}">\n'
            f'    <parent link="{parent}"/>\n    <child link="{child}"/>\n'
            f'    <origin xyz="{v[0]} {v[1]} {v[2] + 0.2}" rpy="{4 * v[3]} {4 * v[4]} {4 * v[5]}"/>\n'
            f'    <axis xyz="{v[6]} {v[7]} 1"/>\n'
            '    <limit lower="-3" upper="3" effort="1" velocity="1"/>\n  </joint>\n')
        parent = child
    parts.append("</robot>\n")
    return "".join(parts)


def run(cli, *args, cwd):
    return subprocess.run([cli, *args], check=True, capture_output=True, text=True, cwd=cwd)


def export_and_expand(cli, tmp_path, template, base, tips):
    """Imports `template`, calibrates it (a perturbed copy, the measurement frame moved, two
    sessions), exports it with `export ros` and expands the xacro with the xacro tool. Returns
    (the output folder, the expanded URDF's text, the robot file's joint names)."""
    tip_args = [a for t in tips for a in ("--tip", t)]
    base_args = ["--base", base] if base else []
    run(cli, "import", "urdf", template, *base_args, *tip_args, "--out", "nominal.toml",
        cwd=tmp_path)
    run(cli, "simulate", "--robot", "nominal.toml", "--postures", "2", "--seed", "5",
        "--perturb-std", "length=0.001,angle=0.003", "--out", "sim.csv", "--truth", "cal.toml",
        cwd=tmp_path)
    with open(tmp_path / "cal.toml", "a") as f:
        for name, v in SESSIONS.items():
            f.write(f'\n[[sessions]]\nname = "{name}"\n')
            keys = ("x", "y", "z", "alpha", "beta", "gamma")
            f.writelines(f"{key} = {x!r}\n" for key, x in zip(keys, v))
    out = tmp_path / "description"
    out.mkdir()
    run(cli, "export", "ros", "--robot", "cal.toml", "--template", template, *base_args,
        *tip_args, "--out", str(out), cwd=tmp_path)
    xacros = [p for p in os.listdir(out) if p.endswith(".urdf.xacro")]
    assert len(xacros) == 1, os.listdir(out)
    # Expanded from elsewhere: the YAML is found beside the xacro, not in the working folder.
    expanded = subprocess.run([xacro_command(), str(out / xacros[0])], check=True,
                              capture_output=True, text=True, cwd="/").stdout
    with open(tmp_path / "cal.toml", "rb") as f:
        import tomllib
        names = [j["name"] for j in tomllib.load(f)["joints"]]
    return out, expanded, names


def check(cli, tmp_path, template, base, tips, sites):
    out, expanded, names = export_and_expand(cli, tmp_path, template, base, tips)
    joints = urdf_joints(expanded)

    # calibration.yaml as xacro reads it: the expanded origins are its values, bit for bit,
    # and its hash is the documented SHA-256 of them.
    with open(out / "calibration.yaml") as f:
        cal = yaml.safe_load(f)
    h = hashlib.sha256()
    for name, o in cal["joints"].items():
        values = [o[k] for k in ("x", "y", "z", "roll", "pitch", "yaw")]
        assert all(type(v) is float for v in values), (name, values)
        assert joints[name][3] + joints[name][4] == values, name
        h.update(name.encode() + b"\0" + struct.pack("<6d", *values))
    assert cal["hash"] == "calib_kinecal_" + h.digest()[:8].hex()

    # The static transforms: the measurement frame below the base, the sessions below it.
    with open(out / "static_transforms.yaml") as f:
        tf = yaml.safe_load(f)["transforms"]
    assert [(t["parent"], t["child"]) for t in tf] == [
        (tf[0]["parent"], "measurement"), ("measurement", "A"), ("measurement", "tracker_2")]
    for t, v in zip(tf[1:], SESSIONS.values()):
        # The robot file holds the global frame in the session's frame: the inverse.
        m = transform(t) @ homogeneous(zyx(v[3], v[4], v[5]), v[:3])
        assert np.abs(m - np.eye(4)).max() < 1e-14, t["child"]
    base_link = tf[0]["parent"]
    placement = np.linalg.inv(transform(tf[0]))

    # Forward kinematics: the expanded URDF behind the placement against `kinecal fk`.
    rng = random.Random(7)
    with open(tmp_path / "postures.csv", "w") as f:
        f.write("posture," + ",".join(f"v{k + 1}" for k in range(len(names))) + "\n")
        f.writelines(f"{p + 1}," + ",".join(repr(rng.uniform(-3, 3)) for _ in names) + "\n" for p in range(50))
    fk = run(cli, "fk", "--robot", "cal.toml", "--postures", "postures.csv", cwd=tmp_path).stdout
    worst = [0.0, 0.0]
    rows = list(csv.DictReader(fk.splitlines()))
    assert len(rows) == 50 * len(tips)
    for row in rows:
        q = {n: float(row[f"v{k + 1}"]) for k, n in enumerate(names)}
        tip = sites[row["site"]]
        added = tip + "_calibrated"
        link = added if any(j[2] == added for j in joints.values()) else tip
        u = placement @ urdf_fk(joints, base_link, link, q)
        f = homogeneous(zyx(float(row["alpha"]), float(row["beta"]), float(row["gamma"])),
                        [float(row["x"]), float(row["y"]), float(row["z"])])
        worst[0] = max(worst[0], np.linalg.norm(u[:3, 3] - f[:3, 3]))
        worst[1] = max(worst[1], np.abs(u[:3, :3] - f[:3, :3]).max())
    assert worst[0] < TOLERANCE and worst[1] < TOLERANCE, worst
    print(f"{template}: largest deviation {worst[0]:.1e} m, {worst[1]:.1e} (rotation)")

    # The launch file, against stand-ins of launch and launch_ros, with the YAML's values.
    check_launch(out, tf)


def check_launch(out, tf):
    made = []

    class Node:
        def __init__(self, **kwargs):
            made.append(kwargs)

    launch = types.ModuleType("launch")
    launch.LaunchDescription = lambda nodes: list(nodes)
    launch_ros = types.ModuleType("launch_ros")
    actions = types.ModuleType("launch_ros.actions")
    actions.Node = Node
    launch_ros.actions = actions
    saved = {k: sys.modules.get(k) for k in ("launch", "launch_ros", "launch_ros.actions")}
    sys.modules.update({"launch": launch, "launch_ros": launch_ros,
                        "launch_ros.actions": actions})
    try:
        spec = importlib.util.spec_from_file_location(
            "static_transforms_launch", out / "static_transforms.launch.py")
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        description = module.generate_launch_description()
    finally:
        for k, v in saved.items():
            if v is None:
                sys.modules.pop(k, None)
            else:
                sys.modules[k] = v
    assert len(description) == len(tf) == len(made)
    for node, t in zip(made, tf):
        assert node["package"] == "tf2_ros"
        assert node["executable"] == "static_transform_publisher"
        a = node["arguments"]
        flags = dict(zip(a[::2], a[1::2]))
        for key in ("x", "y", "z", "qx", "qy", "qz", "qw"):
            assert float(flags["--" + key]) == t[key], key
        assert flags["--frame-id"] == t["parent"]
        assert flags["--child-frame-id"] == t["child"]


def test_ros_export_ur10(cli, tmp_path):
    urdf = os.path.join(SHARED, "urdf", "universal_robots", "urdf_plain", "ur10_robot.urdf")
    if not os.path.exists(urdf):
        if os.environ.get("CI"):
            pytest.fail(f"{urdf} is missing, and CI is set", pytrace=False)
        pytest.skip(f"{SKIP_REASON} ({urdf} not found)")
    check(cli, tmp_path, urdf, "base_link", ["tool0"], {"ee": "tool0", "tool0": "tool0"})


def test_ros_export_panda_with_a_prismatic_finger(cli, tmp_path):
    urdf = os.path.join(SHARED, "urdf", "franka_panda", "panda.urdf")
    if not os.path.exists(urdf):
        if os.environ.get("CI"):
            pytest.fail(f"{urdf} is missing, and CI is set", pytrace=False)
        pytest.skip(f"{SKIP_REASON} ({urdf} not found)")
    check(cli, tmp_path, urdf, "panda_link0", ["panda_leftfinger"], {"ee": "panda_leftfinger", "panda_leftfinger": "panda_leftfinger"})


def test_ros_export_random_six_axis_arm(cli, tmp_path):
    for seed in (1, 2):
        d = tmp_path / f"arm{seed}"
        d.mkdir()
        (d / "arm.urdf").write_text(random_arm_urdf(seed))
        check(cli, d, str(d / "arm.urdf"), None, ["tool0"], {"ee": "tool0", "tool0": "tool0"})


def test_ros_export_two_arm_tree(cli, tmp_path):
    urdf = os.path.join(ROOT, "examples", "trees", "upper_body.urdf")
    check(cli, tmp_path, urdf, None, ["left_marker", "right_marker"],
          {"left_marker": "left_marker", "right_marker": "right_marker", "ee": "right_marker"})


def test_ros_export_calibration_argument_names_another_yaml(cli, tmp_path):
    """calibration:=FILE (relative to the xacro's folder) replaces the YAML beside it."""
    (tmp_path / "arm.urdf").write_text(random_arm_urdf(3))
    out, expanded, _ = export_and_expand(cli, tmp_path, str(tmp_path / "arm.urdf"), None,
                                         ["tool0"])
    with open(out / "calibration.yaml") as f:
        cal = yaml.safe_load(f)
    cal["joints"]["j2"]["x"] = 0.125
    (out / "other").mkdir()
    with open(out / "other" / "mine.yaml", "w") as f:
        yaml.safe_dump(cal, f)
    xacro = next(p for p in os.listdir(out) if p.endswith(".urdf.xacro"))
    other = subprocess.run([xacro_command(), str(out / xacro), "calibration:=other/mine.yaml"],
                           check=True, capture_output=True, text=True).stdout
    assert urdf_joints(other)["j2"][3][0] == 0.125
    assert urdf_joints(expanded)["j2"][3][0] != 0.125


def test_ros_export_through_the_python_door(cli, tmp_path):
    """kinecal.run with an export spec of format ros writes the same files."""
    import kinecal

    (tmp_path / "arm.urdf").write_text(random_arm_urdf(4))
    out, _, _ = export_and_expand(cli, tmp_path, str(tmp_path / "arm.urdf"), None, ["tool0"])
    again = tmp_path / "again"
    again.mkdir()
    doc = kinecal.run({"job": "export", "format": "ros", "robot": str(tmp_path / "cal.toml"),
                       "template": str(tmp_path / "arm.urdf"), "out": str(again)})
    assert sorted(os.listdir(again)) == sorted(os.listdir(out))
    for name in os.listdir(out):
        assert (again / name).read_text() == (out / name).read_text(), name
    assert doc["read_back"].startswith("read back")
    assert sorted(name for name, _ in doc["files"]) == sorted(os.listdir(out))


def test_ros_export_as_a_robot_method(cli, tmp_path):
    """Robot.to_ros gives the files `kinecal export ros` writes, by name."""
    import kinecal

    (tmp_path / "arm.urdf").write_text(random_arm_urdf(5))
    out, _, _ = export_and_expand(cli, tmp_path, str(tmp_path / "arm.urdf"), None, ["tool0"])
    robot = kinecal.Robot.from_toml(str(tmp_path / "cal.toml"))
    with pytest.warns(kinecal.ExportWarning, match="published as the frame `tracker_2`"):
        files = robot.to_ros(str(tmp_path / "arm.urdf"))
    assert sorted(files) == sorted(os.listdir(out))
    for name, text in files.items():
        assert (out / name).read_text() == text, name
    with pytest.raises(kinecal.KinecalError, match="measurement_frame"):
        robot.to_ros(str(tmp_path / "arm.urdf"), measurement_frame="link3")


def test_ros_export_robot_with_a_camera(cli, tmp_path):
    """A UR10 with a wrist camera and a board beside it: the expanded xacro's tool link behind
    the camera's static transform is kinecal's camera frame (the end effector of `kinecal fk`
    times the camera's pose in the robot file, composed here), to 1e-9 m; the board's static
    transform is its estimated pose in the measurement frame."""
    urdf = os.path.join(SHARED, "urdf", "universal_robots", "urdf_plain", "ur10_robot.urdf")
    if not os.path.exists(urdf):
        if os.environ.get("CI"):
            pytest.fail(f"{urdf} is missing, and CI is set", pytrace=False)
        pytest.skip(f"{SKIP_REASON} ({urdf} not found)")
    camera = (0.03, -0.05, 0.04, 0.05, -0.03, 0.02)
    board = (0.8, 0.1, 0.2, 0.3, -0.2, 0.1)
    run(cli, "import", "urdf", urdf, "--base", "base_link", "--tip", "tool0", "--out",
        "nominal.toml", cwd=tmp_path)
    run(cli, "simulate", "--robot", "nominal.toml", "--postures", "2", "--seed", "5",
        "--perturb-std", "length=0.001,angle=0.003", "--out", "sim.csv", "--truth", "cal.toml",
        cwd=tmp_path)
    with open(tmp_path / "cal.toml", "a") as f:
        f.write('\n[[cameras]]\nname = "wrist"\nmount = "ee"\n'
                f"pose = [{', '.join(repr(v) for v in camera)}]\n"
                "fx = 600.0\nfy = 610.0\ncx = 320.0\ncy = 240.0\n"
                "distortion = [-0.2, 0.0, 0.0, 0.0, 0.0]\nwidth = 640\nheight = 480\n")
        f.write('\n[[boards]]\nname = "board"\nmount = "base"\n'
                f"pose = [{', '.join(repr(v) for v in board)}]\n"
                "cols = 9\nrows = 6\nspacing = 0.025\n")
    out = tmp_path / "description"
    out.mkdir()
    run(cli, "export", "ros", "--robot", "cal.toml", "--template", urdf, "--base", "base_link",
        "--tip", "tool0", "--out", str(out), cwd=tmp_path)
    xacros = [p for p in os.listdir(out) if p.endswith(".urdf.xacro")]
    expanded = subprocess.run([xacro_command(), str(out / xacros[0])], check=True,
                              capture_output=True, text=True, cwd="/").stdout
    joints = urdf_joints(expanded)
    with open(out / "static_transforms.yaml") as f:
        tf = {t["child"]: t for t in yaml.safe_load(f)["transforms"]}
    cam, brd = tf["wrist_optical_frame"], tf["board"]
    assert brd["parent"] == "measurement"
    # The board, fixed beside the robot: its pose in the measurement frame as estimated.
    assert np.abs(transform(brd) - homogeneous(zyx(*board[3:]), board[:3])).max() < 1e-14
    base_link = tf["measurement"]["parent"]
    placement = np.linalg.inv(transform(tf["measurement"]))
    import tomllib
    with open(tmp_path / "cal.toml", "rb") as f:
        names = [j["name"] for j in tomllib.load(f)["joints"]]
    rng = random.Random(3)
    with open(tmp_path / "postures.csv", "w") as f:
        f.write("posture," + ",".join(f"v{k + 1}" for k in range(len(names))) + "\n")
        f.writelines(f"{p + 1}," + ",".join(repr(rng.uniform(-3, 3)) for _ in names) + "\n"
                     for p in range(30))
    fk = run(cli, "fk", "--robot", "cal.toml", "--postures", "postures.csv", cwd=tmp_path).stdout
    in_mount = homogeneous(zyx(*camera[3:]), camera[:3])
    worst = 0.0
    for row in csv.DictReader(fk.splitlines()):
        q = {n: float(row[f"v{k + 1}"]) for k, n in enumerate(names)}
        ee = homogeneous(zyx(float(row["alpha"]), float(row["beta"]), float(row["gamma"])),
                         [float(row["x"]), float(row["y"]), float(row["z"])])
        ours = ee @ in_mount
        theirs = placement @ urdf_fk(joints, base_link, cam["parent"], q) @ transform(cam)
        worst = max(worst, np.abs(ours - theirs).max())
    assert worst < TOLERANCE, worst
    print(f"camera: largest deviation {worst:.1e}")
