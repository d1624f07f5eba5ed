#!/usr/bin/env python3
"""Writes models/hrp4/hrp4.urdf, the project's HRP-4-class model, from the figures below.

Every number is either a published HRP-4 figure, a published human segment figure scaled to
the robot, or an estimate; README.md beside this file gives the source of each. Run it from
anywhere: `python3 models/hrp4/make_urdf.py` (standard library only). The URDF is committed;
the simulator's MJCF is generated from the URDF by the Rust code (src/robot/mjcf.rs).

Frames: x forward, y left, z up; the zero posture stands straight with the arms down.
"""

import math
import os

TOTAL_MASS_KG = 39.0  # HRP-4 with batteries (Kaneko et al., Humanoids 2011)

# Winter (2009), Biomechanics and Motor Control of Human Movement, 4th ed., Table 4.1:
# segment mass as a fraction of total body mass.
WINTER = {
    "head_neck": 0.081,
    "thorax_abdomen": 0.355,  # thorax 0.216 + abdomen 0.139
    "pelvis": 0.142,
    "upper_arm": 0.028,
    "forearm": 0.016,
    "hand": 0.006,
    "thigh": 0.100,
    "leg": 0.0465,
    "foot": 0.0145,
}
assert abs(sum(WINTER.values()) + WINTER["upper_arm"] + WINTER["forearm"] + WINTER["hand"]
           + WINTER["thigh"] + WINTER["leg"] + WINTER["foot"] - 1.0) < 1e-9

# Scaled to the robot: with human fractions the half-sitting CoM would be 0.88 m high, while
# HRP-4's is about 0.78 m (its legs carry the big actuators). The leg segments are scaled by
# LEG_SCALE and the thorax-abdomen gives up the difference, so the total stays 39 kg.
LEG_SCALE = 1.45
_moved = sum(2 * WINTER[k] * (LEG_SCALE - 1.0) for k in ("thigh", "leg", "foot"))
for _k in ("thigh", "leg", "foot"):
    WINTER[_k] *= LEG_SCALE
WINTER["thorax_abdomen"] -= _moved

# Lengths, metres.
HIP_Y_OFFSET = 0.08      # hip joint centre from the sagittal plane (feet ~0.18 m apart)
HIP_BELOW_WAIST = 0.09   # hip joint centre below the root (BODY) frame
THIGH = 0.353            # hip to knee
SHANK = 0.353            # knee to ankle
ANKLE_HEIGHT = 0.093     # ankle axis above the sole (published)
SOLE_AHEAD = 0.014       # sole centre ahead of the ankle axis (published)
SOLE_OUT = 0.010         # sole centre outward from the ankle axis (published)
SOLE = (0.24, 0.13)      # sole length x width (published)
CHEST_ABOVE_WAIST = 0.10
NECK_ABOVE_CHEST = 0.335
HEAD_TOP_ABOVE_NECK = 0.186  # gives 1.51 m standing
LIDAR_MOUNT_ABOVE_NECK = 0.05  # the servo's base on the neck (paper Fig. 2)
SHOULDER_Y = 0.175
SHOULDER_ABOVE_CHEST = 0.27
UPPER_ARM = 0.22
FOREARM = 0.20
HAND = 0.10

DEG = math.pi / 180.0


def mass(key, share=1.0):
    return TOTAL_MASS_KG * WINTER[key] * share


class Link:
    def __init__(self, name, m, com, shape, collision=None):
        self.name, self.m, self.com, self.shape, self.collision = name, m, com, shape, collision


def inertia(m, shape):
    """Principal inertia about the centre of mass of a solid shape."""
    kind = shape[0]
    if kind == "cyl":  # radius, length along z
        r, l = shape[1], shape[2]
        ixx = m * (3 * r * r + l * l) / 12.0
        return ixx, ixx, m * r * r / 2.0
    if kind == "box":  # full sizes x, y, z
        a, b, c = shape[1], shape[2], shape[3]
        return m * (b * b + c * c) / 12.0, m * (a * a + c * c) / 12.0, m * (a * a + b * b) / 12.0
    if kind == "sphere":
        i = 0.4 * m * shape[1] ** 2
        return i, i, i
    raise ValueError(kind)


links = []
joints = []  # (name, parent, child, xyz, axis, lower_deg, upper_deg, effort, velocity)
frames = []  # fixed frames: (name, parent, xyz)

SMALL = ("sphere", 0.03)

links.append(Link("BODY", mass("pelvis"), (0.0, 0.0, -0.02), ("box", 0.16, 0.24, 0.16),
                  ("box", (0.0, 0.0, -0.02), (0.16, 0.24, 0.16))))

# The published half-sitting angles (right: hip roll -0.76, ankle roll -0.45 deg; left: 1.15,
# -1.10) leave both soles flat only if the right ankle's roll axis points backward; with a
# common +x axis the right sole would be rolled 1.2 deg. We adopt the mirrored axis.
ANKLE_ROLL_AXIS = {"R": (-1, 0, 0), "L": (1, 0, 0)}

# Legs. Effort (N m) and velocity (rad/s) limits are estimates (README.md).
for side, s in (("R", -1.0), ("L", 1.0)):
    roll = (-35, 35)
    links.append(Link(f"{side}_HIP_Y_LINK", mass("thigh", 0.08), (0, 0, 0), SMALL))
    links.append(Link(f"{side}_HIP_R_LINK", mass("thigh", 0.10), (0, 0, 0), SMALL))
    links.append(Link(f"{side}_HIP_P_LINK", mass("thigh", 0.82), (0, 0, -0.433 * THIGH),
                      ("cyl", 0.06, THIGH), ("capsule", (0, 0, -0.06), (0, 0, -THIGH + 0.06), 0.06)))
    links.append(Link(f"{side}_KNEE_LINK", mass("leg"), (0, 0, -0.433 * SHANK),
                      ("cyl", 0.05, SHANK), ("capsule", (0, 0, -0.05), (0, 0, -SHANK + 0.06), 0.05)))
    links.append(Link(f"{side}_ANKLE_P_LINK", mass("foot", 0.2), (0, 0, 0), SMALL))
    links.append(Link(f"{side}_ANKLE_R_LINK", mass("foot", 0.8), (SOLE_AHEAD, s * SOLE_OUT, -0.6 * ANKLE_HEIGHT),
                      ("box", SOLE[0], SOLE[1], 0.05),
                      ("box", (SOLE_AHEAD, s * SOLE_OUT, -ANKLE_HEIGHT + 0.01), (SOLE[0], SOLE[1], 0.02))))
    joints += [
        (f"{side}_HIP_Y", "BODY", f"{side}_HIP_Y_LINK", (0, s * HIP_Y_OFFSET, -HIP_BELOW_WAIST), (0, 0, 1), -45, 45, 60, 6.0),
        (f"{side}_HIP_R", f"{side}_HIP_Y_LINK", f"{side}_HIP_R_LINK", (0, 0, 0), (1, 0, 0), *roll, 120, 6.0),
        (f"{side}_HIP_P", f"{side}_HIP_R_LINK", f"{side}_HIP_P_LINK", (0, 0, 0), (0, 1, 0), -130, 40, 150, 6.0),
        (f"{side}_KNEE_P", f"{side}_HIP_P_LINK", f"{side}_KNEE_LINK", (0, 0, -THIGH), (0, 1, 0), 0, 150, 200, 6.0),
        (f"{side}_ANKLE_P", f"{side}_KNEE_LINK", f"{side}_ANKLE_P_LINK", (0, 0, -SHANK), (0, 1, 0), -75, 45, 150, 6.0),
        (f"{side}_ANKLE_R", f"{side}_ANKLE_P_LINK", f"{side}_ANKLE_R_LINK", (0, 0, 0), ANKLE_ROLL_AXIS[side], -30, 30, 100, 6.0),
    ]
    frames.append((f"{side}_SOLE", f"{side}_ANKLE_R_LINK", (SOLE_AHEAD, s * SOLE_OUT, -ANKLE_HEIGHT)))

# Trunk, neck and head.
links.append(Link("CHEST_P_LINK", mass("thorax_abdomen", 0.04), (0, 0, 0), SMALL))
links.append(Link("CHEST_Y_LINK", mass("thorax_abdomen", 0.96), (-0.01, 0, 0.13), ("box", 0.20, 0.30, 0.36),
                  ("box", (-0.01, 0, 0.17), (0.20, 0.30, 0.36))))
links.append(Link("NECK_Y_LINK", mass("head_neck", 0.10), (0, 0, 0), SMALL))
links.append(Link("NECK_P_LINK", mass("head_neck", 0.90), (0, 0, 0.09), ("sphere", 0.10),
                  ("sphere", (0, 0, HEAD_TOP_ABOVE_NECK - 0.10), 0.10)))
joints += [
    ("CHEST_P", "BODY", "CHEST_P_LINK", (0, 0, CHEST_ABOVE_WAIST), (0, 1, 0), -10, 60, 150, 4.0),
    ("CHEST_Y", "CHEST_P_LINK", "CHEST_Y_LINK", (0, 0, 0), (0, 0, 1), -60, 60, 100, 4.0),
    ("NECK_Y", "CHEST_Y_LINK", "NECK_Y_LINK", (0, 0, NECK_ABOVE_CHEST), (0, 0, 1), -60, 60, 10, 4.0),
    ("NECK_P", "NECK_Y_LINK", "NECK_P_LINK", (0, 0, 0), (0, 1, 0), -30, 45, 10, 4.0),
]
frames.append(("head", "NECK_P_LINK", (0, 0, LIDAR_MOUNT_ABOVE_NECK)))
frames.append(("head_top", "NECK_P_LINK", (0, 0, HEAD_TOP_ABOVE_NECK)))

# Arms.
for side, s in (("R", -1.0), ("L", 1.0)):
    links.append(Link(f"{side}_SHOULDER_P_LINK", mass("upper_arm", 0.1), (0, 0, 0), SMALL))
    links.append(Link(f"{side}_SHOULDER_R_LINK", mass("upper_arm", 0.1), (0, 0, 0), SMALL))
    links.append(Link(f"{side}_SHOULDER_Y_LINK", mass("upper_arm", 0.8), (0, 0, -0.436 * UPPER_ARM),
                      ("cyl", 0.04, UPPER_ARM), ("capsule", (0, 0, -0.04), (0, 0, -UPPER_ARM + 0.04), 0.04)))
    links.append(Link(f"{side}_ELBOW_P_LINK", mass("forearm", 0.7), (0, 0, -0.06), ("cyl", 0.035, FOREARM / 2),
                      ("capsule", (0, 0, -0.03), (0, 0, -FOREARM / 2), 0.035)))
    links.append(Link(f"{side}_WRIST_Y_LINK", mass("forearm", 0.3), (0, 0, -0.05), ("cyl", 0.03, FOREARM / 2)))
    links.append(Link(f"{side}_WRIST_P_LINK", mass("hand", 0.2), (0, 0, 0), SMALL))
    links.append(Link(f"{side}_WRIST_R_LINK", mass("hand", 0.5), (0, 0, -0.04), ("box", 0.03, 0.08, 0.08),
                      ("box", (0, 0, -0.04), (0.03, 0.08, 0.08))))
    links.append(Link(f"{side}_HAND_J0_LINK", mass("hand", 0.15), (0, 0, -0.02), SMALL))
    links.append(Link(f"{side}_HAND_J1_LINK", mass("hand", 0.15), (0, 0, -0.02), SMALL))
    roll = (-95, 10) if s < 0 else (-10, 95)
    joints += [
        (f"{side}_SHOULDER_P", "CHEST_Y_LINK", f"{side}_SHOULDER_P_LINK", (0, s * SHOULDER_Y, SHOULDER_ABOVE_CHEST), (0, 1, 0), -180, 90, 60, 5.0),
        (f"{side}_SHOULDER_R", f"{side}_SHOULDER_P_LINK", f"{side}_SHOULDER_R_LINK", (0, 0, 0), (1, 0, 0), *roll, 60, 5.0),
        (f"{side}_SHOULDER_Y", f"{side}_SHOULDER_R_LINK", f"{side}_SHOULDER_Y_LINK", (0, 0, 0), (0, 0, 1), -90, 90, 30, 5.0),
        (f"{side}_ELBOW_P", f"{side}_SHOULDER_Y_LINK", f"{side}_ELBOW_P_LINK", (0, 0, -UPPER_ARM), (0, 1, 0), -130, 0, 40, 5.0),
        (f"{side}_WRIST_Y", f"{side}_ELBOW_P_LINK", f"{side}_WRIST_Y_LINK", (0, 0, -FOREARM / 2), (0, 0, 1), -90, 90, 10, 5.0),
        (f"{side}_WRIST_P", f"{side}_WRIST_Y_LINK", f"{side}_WRIST_P_LINK", (0, 0, -FOREARM / 2), (0, 1, 0), -60, 60, 10, 5.0),
        (f"{side}_WRIST_R", f"{side}_WRIST_P_LINK", f"{side}_WRIST_R_LINK", (0, 0, 0), (1, 0, 0), -60, 60, 10, 5.0),
        (f"{side}_HAND_J0", f"{side}_WRIST_R_LINK", f"{side}_HAND_J0_LINK", (0, s * 0.02, -HAND * 0.8), (1, 0, 0), -10, 60, 2, 3.0),
        (f"{side}_HAND_J1", f"{side}_WRIST_R_LINK", f"{side}_HAND_J1_LINK", (0, -s * 0.02, -HAND * 0.8), (1, 0, 0), -60, 10, 2, 3.0),
    ]


def f(x):
    return repr(float(x))


def v(t):
    return " ".join(f(x) for x in t)


def write(path):
    total = sum(l.m for l in links)
    assert abs(total - TOTAL_MASS_KG) < 1e-9, total
    assert len(joints) == 34, len(joints)
    out = ['<?xml version="1.0"?>',
           "<!-- GENERATED by models/hrp4/make_urdf.py from the figures in models/hrp4/README.md. Do not edit. -->",
           '<robot name="hrp4">']
    for l in links:
        ixx, iyy, izz = inertia(l.m, l.shape)
        out.append(f'  <link name="{l.name}">')
        out.append(f'    <inertial><origin xyz="{v(l.com)}" rpy="0 0 0"/><mass value="{f(l.m)}"/>'
                   f'<inertia ixx="{f(ixx)}" ixy="0" ixz="0" iyy="{f(iyy)}" iyz="0" izz="{f(izz)}"/></inertial>')
        if l.collision:
            c = l.collision
            if c[0] == "box":
                geo, xyz = f'<box size="{v(c[2])}"/>', c[1]
            elif c[0] == "sphere":
                geo, xyz = f'<sphere radius="{f(c[2])}"/>', c[1]
            else:  # capsule between two points along z, written as a URDF cylinder
                a, b, r = c[1], c[2], c[3]
                xyz = tuple((p + q) / 2 for p, q in zip(a, b))
                geo = f'<cylinder radius="{f(r)}" length="{f(abs(a[2] - b[2]))}"/>'
            out.append(f'    <collision><origin xyz="{v(xyz)}" rpy="0 0 0"/><geometry>{geo}</geometry></collision>')
        out.append("  </link>")
    for (name, parent, xyz) in frames:
        out.append(f'  <link name="{name}"/>')
    for (name, parent, child, xyz, axis, lo, hi, effort, vel) in joints:
        out.append(f'  <joint name="{name}" type="revolute"><parent link="{parent}"/><child link="{child}"/>'
                   f'<origin xyz="{v(xyz)}" rpy="0 0 0"/><axis xyz="{v(axis)}"/>'
                   f'<limit lower="{f(lo * DEG)}" upper="{f(hi * DEG)}" effort="{f(effort)}" velocity="{f(vel)}"/></joint>')
    for (name, parent, xyz) in frames:
        out.append(f'  <joint name="{name}_frame" type="fixed"><parent link="{parent}"/><child link="{name}"/>'
                   f'<origin xyz="{v(xyz)}" rpy="0 0 0"/></joint>')
    out.append("</robot>")
    with open(path, "w") as fh:
        fh.write("\n".join(out) + "\n")


if __name__ == "__main__":
    write(os.path.join(os.path.dirname(os.path.abspath(__file__)), "hrp4.urdf"))
