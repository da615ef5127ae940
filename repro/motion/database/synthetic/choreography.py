"""The choreography of one synthetic clip: timeline design, trunk, feet and limb IK (:func:`synthetic_clip`).

A :class:`_Builder` designs one clip (a straight punch, a front / side / round kick or
an idle stance): first the timeline and the trunk tracks (``design_*``), then the feet
on the ground (``legs_planted``), then :meth:`_Builder.solve` poses it: the root height
that keeps the planted legs bent, trunk FK, the limb aimed at the target height at the
hit, and the hinge-clamped two-bone IK of every limb.  All random draws come from one
seeded generator, in a fixed order (the designs draw everything before any FK).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from repro.checks import as_choice, as_int, as_real, as_real_array, describe
from repro.errors import MotionError
from repro.motion.database.annotation import hit_point_trajectory
from repro.motion.core.motion import Motion
from repro.motion.core.quaternion import (
    axis_angle_quat,
    euler_to_quat,
    quat_conjugate,
    quat_multiply,
    quat_power,
    quat_rotate,
    slerp,
)
from repro.motion.database.synthetic.ik import IKSolution, Limb, flexion_at, limb_of, limb_reach, two_bone
from repro.motion.database.synthetic.moves import (
    HIT_LEVELS,
    HIT_POINTS,
    KIND_SEMANTICS,
    KINDS,
    SIDES,
    TARGET_HEIGHT_FRACTION,
)
from repro.motion.database.synthetic.skeleton import (
    DEFAULT_FPS,
    JOINT_INDEX,
    JOINT_NAMES,
    PARENTS,
    REF_LENGTHS,
    REFERENCE_HEIGHT_M,
    scale_of,
    synthetic_skeleton,
)
from repro.motion.database.synthetic.tracks import (
    UNIT_X,
    UNIT_Y,
    dir_track,
    ease_smooth,
    rad,
    spherical,
    track,
    unit,
)

__all__ = ["synthetic_clip"]


#: The trunk of the round and side kicks, which turn the body away from the kicking side: the
#: ranges (degrees) of the yaw at the hit, at the chamber and at the recoil, of the pitch and roll
#: at the hit per level (high, middle, low), the root's shift back at the hit (x the actor's
#: scale, metres) and the spine's share of the yaw.
_TURNING_KICKS: dict[str, tuple] = {
    "kick_round": ((55, 70), (20, 30), (35, 45), [(8, 14), (4, 8), (0, 2)], [(15, 22), (8, 12), (2, 6)], -0.03, 0.35),
    "kick_side": ((65, 75), (55, 62), (55, 62), [(4, 8), (2, 5), (0, 2)], [(28, 35), (16, 22), (6, 12)], -0.06, 0.3),
}


# ---------------------------------------------------------------- clip design
class _Leg(NamedTuple):
    """Ground contact design of one leg.

    On the ground the foot is either flat or, around a kick's lift-off and landing,
    pivoting on the ball of the foot (heel raised by ``heel``, toes kept flat by
    bending the toe joint); ``w_pos`` blends from that ground pose (0) to the flight
    design (1).
    """

    yaw: float  # foot yaw on the ground (radians, about +Y)
    ankle: np.ndarray  # (3,) ankle position of the flat foot
    ground_ankle: np.ndarray  # (F, 3) ankle target on the ground (moves only with a raised heel)
    ground_q: np.ndarray  # (F, 4) world rotation of the foot on the ground
    heel: np.ndarray  # (F,) heel-raise angle, radians
    w_pos: np.ndarray  # (F,) 0 = on the ground, 1 = following the flight design


class _Builder:
    """Designs one clip: trunk tracks, then root height, trunk FK, hit target, limb IK."""

    def __init__(self, kind: str, side: str, level: str, actor_height: float, rng: np.random.Generator, fps: float):
        self.kind, self.side, self.level = kind, side, level
        self.height = float(actor_height)
        self.s = scale_of(actor_height)
        self.rng = rng
        self.fps = float(fps)
        self.sg = 1.0 if side == "left" else -1.0  # +1: the striking limb is on +X
        self.hit_side = "Left" if self.sg > 0 else "Right"
        self.lead_side = "Right" if self.sg > 0 else "Left"
        self.skel = synthetic_skeleton(actor_height)
        s, sg, r = self.s, self.sg, rng
        # fighting stance: lead foot on the side opposite to the striking limb
        w = r.uniform(0.12, 0.16) * s
        d = r.uniform(0.19, 0.25) * s
        ah = REF_LENGTHS["ankle"] * s
        self.feet = {
            self.lead_side: (np.array([-sg * w, ah, d]), -sg * rad(r.uniform(10, 20))),
            self.hit_side: (np.array([sg * w, ah, -d]), sg * rad(r.uniform(35, 50))),
        }
        self.center0 = np.array([r.uniform(-0.01, 0.01) * s, r.uniform(-0.04, -0.01) * s])
        self.yaw0 = sg * rad(r.uniform(20, 30))
        self.pitch0 = rad(r.uniform(1, 4))
        self.twist0 = sg * rad(r.uniform(3, 8))
        self.guard = {  # wrist position and elbow pole in the chest (Spine1) frame
            self.hit_side: (np.array([sg * r.uniform(0.08, 0.12), r.uniform(0.18, 0.22), r.uniform(0.24, 0.28)]) * s,
                            np.array([sg * 0.35, -1.0, -0.1])),
            self.lead_side: (np.array([-sg * r.uniform(0.06, 0.10), r.uniform(0.22, 0.26), r.uniform(0.34, 0.38)]) * s,
                             np.array([-sg * 0.35, -1.0, 0.0])),
        }  # fmt: skip
        self.target_height = None
        self.hit_frame = None
        self.arm_keys: dict[str, tuple[list, list, list]] = {}

    # ------------------------------------------------------------ timeline helpers
    def sec(self, lo: float, hi: float) -> float:
        """A random duration in frames."""
        return self.rng.uniform(lo, hi) * self.fps

    def set_frames(self, last_key: float) -> None:
        self.F = int(math.ceil(last_key)) + 1
        self.t = np.arange(self.F, dtype=float)

    # ------------------------------------------------------------ the three designs
    def design_punch(self) -> None:
        r, s, sg, lv = self.rng, self.s, self.sg, self.level
        f_w = self.sec(0.15, 0.30)
        f_c = f_w + self.sec(0.20, 0.30)
        f_h = float(round(f_c + self.sec(0.20, 0.26)))
        f_r = f_h + self.sec(0.30, 0.40)
        end = f_r + self.sec(0.15, 0.30)
        self.set_frames(end)
        self.hit_frame = int(f_h)
        self.phases = {"windup": f_w, "chamber": f_c, "hit": f_h, "recovered": f_r}
        t = self.t
        y0, p0, tw0 = self.yaw0, self.pitch0, self.twist0
        lean = {"high": (0, 4), "middle": (4, 8), "low": (12, 18)}[lv]
        drop = {"high": 0.0, "middle": 0.03, "low": 0.10}[lv] * s
        keys = [0.0, f_w, f_c, f_h, f_r, end]
        ez = ["smooth", "smooth", "smooth", "smooth", "smooth"]
        yaw_c, yaw_h = y0 + sg * rad(r.uniform(3, 8)), -sg * rad(r.uniform(0, 10))  # wind back, turn through
        self.yaw = track(t, list(zip(keys, [y0, y0, yaw_c, yaw_h, y0, y0])), ez)
        self.pitch = track(t, list(zip(keys, [p0, p0, p0, rad(r.uniform(*lean)), p0, p0])), ez)
        self.roll = np.zeros(self.F)
        ez_s = ["smooth", "smooth", "strike", "smooth", "smooth"]
        tw_c, tw_h = sg * rad(r.uniform(10, 18)), -sg * rad(r.uniform(12, 22))  # shoulders lag the hips
        twist = track(t, list(zip(keys, [tw0, tw0, tw_c, tw_h, tw0, tw0])), ez_s)
        lean_h = rad(r.uniform(5, 10)) if lv == "low" else rad(r.uniform(0, 3))
        slean = track(t, list(zip(keys, [0, 0, 0, lean_h, 0, 0])), ez)
        self.spine = np.stack([twist, slean, np.zeros(self.F)], axis=1)
        c0 = self.center0
        lunge = np.array([-sg * 0.03 * s, r.uniform(0.05, 0.09) * s])
        self.root_xz = track(t, list(zip(keys, [c0, c0, c0 + [0, -0.02 * s], c0 + lunge, c0, c0])), ez)
        self.dy = track(t, list(zip(keys, [0, 0, -0.01 * s, -drop, 0, 0])), ez)
        prot = track(t, list(zip(keys, [0, 0, -0.10, rad(r.uniform(12, 20)), 0, 0])), ez_s)
        self.clav = {self.hit_side: np.stack([prot, np.zeros(self.F)], 1), self.lead_side: np.zeros((self.F, 2))}
        # arms: the striking fist goes guard -> chamber at the hip -> target -> guard;
        # the lead hand reaches out while the other chambers, then pulls back
        g, gp = self.guard[self.hit_side]
        chamber = np.array([sg * r.uniform(0.18, 0.21), r.uniform(-0.12, -0.08), r.uniform(-0.06, -0.02)]) * s
        self.arm_keys[self.hit_side] = (
            [(0.0, g), (f_w, g), (f_c, chamber), (f_h, None), (f_r, g), (end, g)],
            [(0.0, gp), (f_w, gp), (f_c, np.array([sg * 0.3, -0.2, -1.0])), (f_h, np.array([sg * 0.3, -1.0, -0.3])),
             (f_r, gp), (end, gp)],
            ez_s,
        )  # fmt: skip
        lg, lgp = self.guard[self.lead_side]
        reach = lg + np.array([sg * 0.03, -0.02, r.uniform(0.06, 0.12)]) * s
        pulled = np.array([-sg * r.uniform(0.08, 0.12), r.uniform(0.08, 0.14), r.uniform(0.10, 0.16)]) * s
        self.arm_keys[self.lead_side] = (
            [(0.0, lg), (f_w, lg), (f_c, reach), (f_h, pulled), (f_r, lg), (end, lg)],
            [(0.0, lgp), (f_w, lgp), (f_c, lgp), (f_h, np.array([-sg * 0.4, -1.0, -0.6])), (f_r, lgp), (end, lgp)],
            ez,
        )
        self.legs_planted()
        self.flex_hit = rad(r.uniform(6, 14))
        self.target_height = (TARGET_HEIGHT_FRACTION["punch"][lv] + r.uniform(-0.02, 0.02)) * self.height
        self.target_x = self.center0[0]

    def design_kick(self) -> None:
        keys, li = self.kick_timeline()
        self.kick_trunk(keys, li)
        self.kick_arms(keys)
        self.kick_shapes(li)
        self.legs_planted(kick=True)

    def kick_timeline(self) -> tuple[list[float], int]:
        """Key frames of a kick (weight shift, lift-off, chamber, hit, rechamber, touch-down, recovery)."""
        lv, kind = self.level, self.kind
        f_ws = self.sec(0.15, 0.30)  # weight starts moving onto the support foot
        shift = self.sec(0.28, 0.36)  # duration of the weight shift (mirrored at the landing)
        heel_lag = self.sec(0.08, 0.14)  # the heel rises that long after the shift starts
        f_ho = f_ws + heel_lag  # the kicking heel starts to rise
        f_l = float(round(f_ws + shift))  # lift-off from the ball of the foot
        li = {"high": 0, "middle": 1, "low": 2}[lv]
        f_c = f_l + self.sec(0.33, 0.43) + (0.12, 0.06, 0.0)[li] * self.fps  # knee chambered
        strike = {"kick_front": (0.19, 0.24), "kick_side": (0.12, 0.16), "kick_round": (0.16, 0.21)}[kind]
        f_h = float(round(f_c + self.sec(*strike)))
        f_r = f_h + self.sec(0.20, 0.28)  # rechambered
        f_d = float(round(f_r + self.sec(0.35, 0.45) + (0.12, 0.06, 0.0)[li] * self.fps))  # touch-down on the ball
        f_e = f_d + shift  # weight back in stance
        f_hd = f_e - heel_lag  # heel down (the lift-off, time-reversed)
        end = f_e + self.sec(0.10, 0.25)
        self.set_frames(end)
        self.hit_frame = int(f_h)
        self.phases = {"weight_shift": f_ws, "heel_off": f_ho, "lift_off": f_l, "chamber": f_c, "hit": f_h,
                       "rechamber": f_r, "touch_down": f_d, "heel_down": f_hd, "recovered": f_e}  # fmt: skip
        keys = [0.0, f_ws, f_l, f_c, f_h, f_r, f_d, f_e, end]
        return keys, li

    def kick_trunk(self, keys: list[float], li: int) -> None:
        """Yaw, pitch, roll, spine, root and clavicle tracks of a kick."""
        r, s, sg, kind = self.rng, self.s, self.sg, self.kind
        t = self.t
        ez = ["smooth"] * 8
        y0, p0 = self.yaw0, self.pitch0
        if kind == "kick_front":
            y_h = sg * rad(r.uniform(-5, 5))
            yc, yr = y_h, y_h
            pitch_h = -rad(r.uniform(*[(15, 22), (6, 12), (0, 4)][li]))
            roll_h = sg * rad(r.uniform(0, 4))
            back = np.array([0.0, -0.04 * s])
            kfac = 0.3
        else:  # the kicks that turn the body away from the kicking side
            yaw_hit, yaw_chamber, yaw_recoil, pitch, roll, back_z, kfac = _TURNING_KICKS[kind]
            y_h = -sg * rad(r.uniform(*yaw_hit))
            yc, yr = -sg * rad(r.uniform(*yaw_chamber)), -sg * rad(r.uniform(*yaw_recoil))
            pitch_h = -rad(r.uniform(*pitch[li]))
            roll_h = sg * rad(r.uniform(*roll[li]))
            back = np.array([0.0, back_z * s])
        yaws = [y0, y0, y0 + 0.3 * (yc - y0), yc, y_h, yr, y0 + 0.4 * (yr - y0), y0, y0]
        self.yaw = track(t, list(zip(keys, yaws)), ez)
        self.pitch = track(t, list(zip(keys, [p0, p0, p0, p0 + 0.6 * (pitch_h - p0), pitch_h,
                                               p0 + 0.6 * (pitch_h - p0), p0, p0, p0])), ez)  # fmt: skip
        self.roll = track(t, list(zip(keys, [0, 0, 0, 0.6 * roll_h, roll_h, 0.6 * roll_h, 0, 0, 0])), ez)
        twist = np.array([self.twist0 - kfac * (y - y0) for y in yaws])
        crunch = rad(r.uniform(3, 8)) if kind == "kick_front" else 0.0
        self.spine = np.stack([
            track(t, list(zip(keys, twist)), ez),
            track(t, list(zip(keys, [0, 0, 0, crunch, 0.3 * crunch, crunch, 0, 0, 0])), ez),
            np.zeros(self.F),
        ], axis=1)  # fmt: skip
        sup_ankle = self.feet[self.lead_side][0]
        c0 = self.center0
        c_sup = np.array([sup_ankle[0] + sg * 0.02 * s, sup_ankle[2] - 0.03 * s])
        # the weight moves over the support foot while the kicking heel rises (85 % at lift-off)
        xz = [c0, c0, c0 + 0.85 * (c_sup - c0), c_sup, c_sup + back, c_sup, c0 + 0.85 * (c_sup - c0), c0, c0]
        self.root_xz = track(t, list(zip(keys, xz)), ez)
        rise = [0, 0, 0.01, 0.03, 0.04, 0.03, 0.01, 0, 0]
        self.dy = track(t, list(zip(keys, np.array(rise) * s)), ez)
        self.clav = {self.hit_side: np.zeros((self.F, 2)), self.lead_side: np.zeros((self.F, 2))}

    def kick_arms(self, keys: list[float]) -> None:
        """Arms stay in guard; the kicking side's arm swings down and back for balance."""
        r, s, sg = self.rng, self.s, self.sg
        ez = ["smooth"] * 8
        g, gp = self.guard[self.hit_side]
        low = np.array([sg * r.uniform(0.20, 0.26), r.uniform(-0.14, -0.08), r.uniform(-0.04, 0.02)]) * s
        mid = 0.5 * (g + low) + np.array([sg * 0.04, 0, 0]) * s
        p_low = np.array([sg * 0.3, 0.0, -1.0])
        self.arm_keys[self.hit_side] = (
            list(zip(keys, [g, g, g, mid, low, mid, g, g, g])),
            list(zip(keys, [gp, gp, gp, gp + p_low, p_low, gp + p_low, gp, gp, gp])),
            ez,
        )
        lg, lgp = self.guard[self.lead_side]
        lg2 = lg + np.array([sg * 0.03, 0.02, -0.06]) * s
        self.arm_keys[self.lead_side] = (list(zip(keys, [lg, lg, lg, lg2, lg2, lg2, lg, lg, lg])),
                                         list(zip(keys, [lgp] * 9)), ez)  # fmt: skip

    def kick_shapes(self, li: int) -> None:
        """Hit flexion, target height, heel, toe, chamber and ankle designs of a kick."""
        r, sg, lv, kind = self.rng, self.sg, self.level, self.kind
        ph = self.phases
        f_ho, f_l, f_c, f_h = ph["heel_off"], ph["lift_off"], ph["chamber"], ph["hit"]
        f_r, f_d, f_hd = ph["rechamber"], ph["touch_down"], ph["heel_down"]
        self.flex_hit = rad(r.uniform(5, 10))
        self.target_height = (TARGET_HEIGHT_FRACTION["kick"][lv] + r.uniform(-0.02, 0.02)) * self.height
        self.target_x = self.center0[0]
        self.kick_keys = (f_l, f_c, f_h, f_r, f_d)
        self.heel_keys = [(f_ho, 0.0), (f_l, rad(r.uniform(35, 45))), (f_d, None), (f_hd, 0.0)]
        self.toe_design = {"kick_front": -r.uniform(20, 35), "kick_round": 0.0, "kick_side": -r.uniform(5, 15)}[kind]
        # chamber and rechamber shapes, drawn now so the random stream does not depend on FK
        self.chamber = {
            "thigh_el": rad([r.uniform(15, 25), r.uniform(-2, 8), r.uniform(-30, -20)][li]),
            "flex": rad(r.uniform(105, 120)),
            "knee_az": sg * rad(r.uniform(20, 35)),
            "re": r.uniform(0.9, 1.1),
        }
        self.ankle_design = {"kick_front": r.uniform(35, 45), "kick_round": r.uniform(40, 50),
                             "kick_side": -r.uniform(5, 15)}[kind]  # fmt: skip

    def design_stance(self) -> None:
        r, s = self.rng, self.s
        n = int(r.integers(4, 6))
        step = [self.sec(0.35, 0.5) for _ in range(n)]
        keys = np.concatenate([[0.0], np.cumsum(step)])
        self.set_frames(keys[-1])
        self.hit_frame = -1
        self.phases = {}
        t, K = self.t, len(keys)
        ez = ["smooth"] * (K - 1)

        def jitter(base, amp, fixed_ends=True):
            base = np.asarray(base, float)
            vals = [base + r.uniform(-1, 1, size=base.shape) * amp for _ in range(K)]
            if fixed_ends:
                vals[0] = vals[-1] = base
            return vals

        self.yaw = track(t, list(zip(keys, jitter(self.yaw0, rad(3)))), ez)
        self.pitch = track(t, list(zip(keys, jitter(self.pitch0, rad(1.5)))), ez)
        self.roll = track(t, list(zip(keys, jitter(0.0, rad(1.0)))), ez)
        self.spine = np.stack([track(t, list(zip(keys, jitter(self.twist0, rad(3)))), ez),
                               track(t, list(zip(keys, jitter(0.0, rad(2)))), ez),
                               np.zeros(self.F)], axis=1)  # fmt: skip
        self.root_xz = track(t, list(zip(keys, jitter(self.center0, 0.015 * s))), ez)
        dys = [-abs(v) for v in jitter(0.0, 0.02 * s)]
        self.dy = track(t, list(zip(keys, dys)), ez)
        self.clav = {k: np.zeros((self.F, 2)) for k in ("Left", "Right")}
        for side in ("Left", "Right"):
            g, gp = self.guard[side]
            self.arm_keys[side] = (list(zip(keys, jitter(g, 0.02 * s))), list(zip(keys, [gp] * K)), ez)
        self.legs_planted()
        self.flex_hit = None

    def legs_planted(self, kick: bool = False) -> None:
        s = self.s
        foot = np.array([0.0, -REF_LENGTHS["ankle"], REF_LENGTHS["foot"]]) * s  # ankle -> ball of the foot
        self.legs = {}
        for side, (ankle, yaw) in self.feet.items():
            w = np.zeros(self.F)
            heel = np.zeros(self.F)
            if kick and side == self.hit_side:
                f_l, f_c, f_h, f_r, f_d = self.kick_keys
                w = track(self.t, [(f_l, 0.0), (f_c, 1.0), (f_r, 1.0), (f_d, 0.0)])
                hk = self.heel_keys
                hk[2] = (hk[2][0], hk[1][1])
                heel = track(self.t, hk)
            q_yaw = axis_angle_quat(UNIT_Y, np.full(self.F, yaw))
            ground_q = quat_multiply(q_yaw, axis_angle_quat(UNIT_X, heel))
            ball = ankle + quat_rotate(q_yaw[0], foot)
            ground_ankle = ball - quat_rotate(ground_q, foot[None])
            self.legs[side] = _Leg(yaw, ankle, ground_ankle, ground_q, heel, w)

    # ------------------------------------------------------------ solving
    def trunk_rotations(self) -> np.ndarray:
        """(F, J, 4) local rotations of root, spine, neck, head and clavicles; identity elsewhere."""
        F = self.F
        q = np.zeros((F, len(JOINT_NAMES), 4))
        q[..., 3] = 1.0
        q[:, 0] = euler_to_quat("YXZ", np.stack([self.yaw, self.pitch, self.roll], 1), degrees=False)
        half = 0.5 * self.spine
        q_sp = euler_to_quat("YXZ", half, degrees=False)
        q[:, JOINT_INDEX["Spine"]] = q_sp
        q[:, JOINT_INDEX["Spine1"]] = q_sp
        chest = quat_multiply(q[:, 0], quat_multiply(q_sp, q_sp))
        # head: 80 % of the way back to facing the target (+Z, upright), split over neck and head
        nh = quat_power(quat_conjugate(chest), 0.4)
        q[:, JOINT_INDEX["Neck"]] = nh
        q[:, JOINT_INDEX["Head"]] = nh
        for side, sgn in (("Left", 1.0), ("Right", -1.0)):
            prot, elev = self.clav[side][:, 0], self.clav[side][:, 1]
            # protraction brings the shoulder forward (+Z), elevation raises it
            q[:, JOINT_INDEX[side + "Shoulder"]] = euler_to_quat("YZ", np.stack([-sgn * prot, sgn * elev], 1), degrees=False)
        return q

    def solve_root_height(self, q: np.ndarray) -> np.ndarray:
        """Root height per frame: the design, lowered smoothly where a planted leg could not reach."""
        off = self.skel.offsets
        L = REF_LENGTHS["thigh"] * self.s + REF_LENGTHS["shin"] * self.s
        bound = np.full(self.F, np.inf)
        stance_bound = np.inf
        for side, leg in self.legs.items():
            hip_rel = quat_rotate(q[:, 0], off[JOINT_INDEX[side + "UpLeg"]][None])  # (F, 3)
            planted = leg.w_pos == 0.0
            other_flying = np.any([self.legs[o].w_pos > 0.0 for o in self.legs if o != side], axis=0)
            # knee flexion >= 2 acos(r): 16 deg on a single support leg, 20 deg in double support
            r_max = np.where(other_flying, 0.99, 0.985)
            ga = leg.ground_ankle
            horiz = np.hypot(self.root_xz[:, 0] + hip_rel[:, 0] - ga[:, 0],
                             self.root_xz[:, 1] + hip_rel[:, 2] - ga[:, 2])  # fmt: skip
            ymax = ga[:, 1] - hip_rel[:, 1] + np.sqrt(np.maximum((r_max * L) ** 2 - horiz**2, 0.0))
            bound = np.where(planted, np.minimum(bound, ymax), bound)
            # the stance itself: knees bent by about 26 degrees (r = 0.975)
            y_st = ga[0, 1] - hip_rel[0, 1] + math.sqrt(max((0.975 * L) ** 2 - horiz[0] ** 2, 0.0))
            stance_bound = min(stance_bound, y_st)
        y = stance_bound + self.dy
        excess = np.maximum(y - bound + 1e-6 * self.s, 0.0)
        # lower the root where needed: over each run of frames with an excess, by the
        # run's largest excess, easing in and out over 0.1 s outside the run (C2, and
        # exactly zero elsewhere, so the stance at both ends is untouched)
        k = max(2.0, 0.1 * self.fps)
        t = self.t
        for a, b in _runs(excess > 0):
            up = ease_smooth(np.clip((t - (a - k)) / k, 0.0, 1.0))
            down = ease_smooth(np.clip(((b - 1 + k) - t) / k, 0.0, 1.0))
            y = y - excess[a:b].max() * np.minimum(up, down)
        return y

    def chest_pose(self, gq, gp):
        j = JOINT_INDEX["Spine1"]
        return gq[:, j], gp[:, j]

    def solve(self) -> tuple[Motion, dict]:
        s, F = self.s, self.F
        q = self.trunk_rotations()
        root = np.column_stack([self.root_xz[:, 0], self.solve_root_height(q), self.root_xz[:, 1]])
        pos = np.broadcast_to(self.skel.offsets, (F, len(JOINT_NAMES), 3)).copy()
        pos[:, 0] = root
        trunk = _replace(self.skel, rotations=q, positions=pos)
        gq, gp = trunk.global_transforms()
        cq, cp = self.chest_pose(gq, gp)

        arms = {side: limb_of(side, "arm", s) for side in ("Left", "Right")}
        legs = {side: limb_of(side, "leg", s) for side in ("Left", "Right")}
        h = self.hit_frame
        hit_world = None
        if self.kind == "punch":
            hit_world = self.aim_punch(arms[self.hit_side], gq, gp, cq, cp)
        elif self.kind != "stance":
            hit_world = self.aim_kick(legs[self.hit_side], gq, gp)

        # ---- arms
        for side, limb in arms.items():
            wkeys, pkeys, ez = self.arm_keys[side]
            if any(v is None for _, v in wkeys):
                w_chest = quat_rotate(quat_conjugate(cq[h]), hit_world["wrist"] - cp[h])
                wkeys = [(k, w_chest if v is None else v) for k, v in wkeys]
            w_local = track(self.t, wkeys, ez)
            p_local = dir_track(self.t, pkeys, ez)
            target = cp + quat_rotate(cq, w_local)
            pole = quat_rotate(cq, p_local)
            ik = two_bone(limb, gp[:, JOINT_INDEX[limb.upper]], target, pole)
            parent = gq[:, PARENTS[JOINT_INDEX[limb.upper]]]
            q[:, JOINT_INDEX[limb.upper]] = quat_multiply(quat_conjugate(parent), ik.q_upper_world)
            q[:, JOINT_INDEX[limb.middle]] = ik.q_middle_local
            if side == self.hit_side and self.kind == "punch":
                self.check_reached(ik, [h], f"{side} arm at the hit")

        # ---- legs
        self.contacts = {}
        for side, limb in legs.items():
            leg = self.legs[side]
            hip = gp[:, JOINT_INDEX[limb.upper]]
            fwd = np.array([math.sin(leg.yaw), 0.0, math.cos(leg.yaw)])
            kicking = side == self.hit_side and self.kind.startswith("kick")
            if kicking:
                fl_target, fl_pole, ankle_local = self.kick_flight(limb, hip, hit_world)
                w = leg.w_pos[:, None]
                ga = leg.ground_ankle
                target = self.soft_reach(limb, hip, ga + w * (fl_target - ga), leg.w_pos)
                pole = (1 - w) * fwd + w * fl_pole
            else:
                target = leg.ground_ankle
                pole = np.broadcast_to(fwd, (F, 3))
                ankle_local = None
            ik = two_bone(limb, hip, target, pole)
            planted = np.flatnonzero(leg.w_pos == 0.0)
            self.check_reached(ik, planted, f"planted {side} foot")
            if side == self.hit_side and self.kind.startswith("kick"):
                self.check_reached(ik, [h], f"{side} leg at the hit")
            q[:, JOINT_INDEX[limb.upper]] = quat_multiply(quat_conjugate(gq[:, 0]), ik.q_upper_world)
            q[:, JOINT_INDEX[limb.middle]] = ik.q_middle_local
            ground_local = quat_multiply(quat_conjugate(ik.q_lower_world), leg.ground_q)
            toe = -leg.heel  # keeps the toes flat on the ground while the heel is raised
            if ankle_local is None:
                q[:, JOINT_INDEX[limb.end]] = ground_local
            else:
                w_foot = leg.w_pos**3  # the foot turns only once it is off the ground
                q[:, JOINT_INDEX[limb.end]] = slerp(ground_local, ankle_local, w_foot[:, None])
                toe = toe * (1.0 - w_foot) + w_foot * rad(self.toe_design)
            q[:, JOINT_INDEX[side + "ToeBase"]] = axis_angle_quat(UNIT_X, toe)
            on_ground = leg.w_pos == 0.0
            self.contacts[side + "Foot"] = _runs(on_ground & (leg.heel == 0.0))
            self.contacts[side + "ToeBase"] = _runs(on_ground)
        motion = _replace(self.skel, rotations=q, positions=pos, frame_time=1.0 / self.fps, source=None)
        return motion, hit_world

    def soft_reach(self, limb: Limb, hip: np.ndarray, target: np.ndarray, w: np.ndarray) -> np.ndarray:
        """Keep the kicking foot's lift-off and landing blend within reach, smoothly.

        While the foot blends between the ground and the flight design (``0 < w < 1``)
        the hip keeps moving and the blended target can end up slightly beyond the leg's
        reach.  Hip-to-target distances above ``d0 = 0.99 L`` (never reached on planted
        frames) are compressed with ``d0 + k tanh((d - d0) / k)`` below the distance at
        the hit, so the IK never clamps and the leg is longest at the hit.
        """
        rel = target - hip
        d = np.linalg.norm(rel, axis=-1)
        d0 = 0.99 * (limb.l1 + limb.l2)
        k = 0.999 * (limb_reach(limb, self.flex_hit) - d0)
        m = (w > 0.0) & (w < 1.0) & (d > d0)
        out = target.copy()
        out[m] = hip[m] + rel[m] * ((d0 + k * np.tanh((d[m] - d0) / k)) / d[m])[:, None]
        return out

    @staticmethod
    def check_reached(ik: IKSolution, frames, what: str) -> None:
        frames = np.asarray(frames, dtype=int)
        if frames.size and np.max(ik.miss[frames]) > 1e-6:
            raise MotionError(f"internal error: {what} out of reach by {np.max(ik.miss[frames]):.3g} m")

    # ------------------------------------------------------------ aiming the hit
    def aim(self, limb: Limb, S: np.ndarray, pole_fn, end_fn, flex: float) -> dict:
        """Direction of the limb at the hit so that the hit point lands at the target height.

        The limb is posed with flexion ``flex`` (so its reach is fixed) and turned about
        its root ``S`` (elevation and azimuth) until the hit point ``end_fn(ik)`` is at
        the target height above the ground and at the target's lateral position.
        """
        D = limb_reach(limb, flex)
        el, az = 0.0, 0.0
        for _ in range(8):
            W = S + D * spherical(az, el)
            ik = two_bone(limb, S[None], W[None], pole_fn(spherical(az, el))[None])
            P = end_fn(ik, W)
            v = P - S
            rho = np.linalg.norm(v)
            el_p = math.asin(np.clip(v[1] / rho, -1, 1))
            el_t = math.asin(np.clip((self.target_height - S[1]) / rho, -0.95, 0.95))
            el = float(np.clip(el + el_t - el_p, -1.2, 1.2))
            hz = math.hypot(v[0], v[2])
            az_p = math.atan2(v[0], v[2])
            az_t = math.asin(np.clip((self.target_x - S[0]) / max(hz, 1e-9), -0.6, 0.6))
            az = float(az + az_t - az_p)
        W = S + D * spherical(az, el)
        ik = two_bone(limb, S[None], W[None], pole_fn(spherical(az, el))[None])
        return {"wrist": W, "dir": spherical(az, el), "hit_point": end_fn(ik, W), "az": az, "el": el}

    def aim_punch(self, limb, gq, gp, cq, cp) -> dict:
        h = self.hit_frame
        S = gp[h, JOINT_INDEX[limb.upper]]
        pole_chest = unit(self.arm_keys[self.hit_side][1][3][1])
        pole = quat_rotate(cq[h], pole_chest)
        fist = REF_LENGTHS["fist"] * self.s

        def end_fn(ik, W):
            return (W + fist * quat_rotate(ik.q_lower_world, limb.u[None]))[0]

        return self.aim(limb, S, lambda d: pole, end_fn, self.flex_hit)

    def kick_pole(self, dirs: np.ndarray, az_hit: float) -> np.ndarray:
        """Knee direction of the kicking leg for hip->ankle directions ``dirs`` (F, 3).

        Front kick: the knee leads upwards in the vertical plane of the kick; round kick:
        it leads horizontally in the direction of the swing; side kick: horizontally
        (the pelvis faces sideways) and upwards (the knee is lifted in the chamber).
        Each is perpendicular to ``dirs`` and vanishes only for vertical ``dirs`` (round
        and side kicks), where the ground pose dominates the blend.
        """
        if self.kind == "kick_front":
            f = np.array([math.sin(az_hit), 0.0, math.cos(az_hit)])
            return np.cross(np.cross(f, UNIT_Y), dirs)
        pole = -self.sg * np.cross(UNIT_Y, dirs)
        if self.kind == "kick_side":
            up = UNIT_Y - np.sum(dirs * UNIT_Y, axis=-1, keepdims=True) * dirs
            pole = pole + 0.6 * np.linalg.norm(pole, axis=-1, keepdims=True) * up
        return pole

    def aim_kick(self, limb, gq, gp) -> dict:
        h = self.hit_frame
        S = gp[h, JOINT_INDEX[limb.upper]]
        toe = np.array([0.0, -REF_LENGTHS["ankle"], REF_LENGTHS["foot"]]) * self.s
        ankle_q = axis_angle_quat(UNIT_X, rad(self.ankle_design))

        def end_fn(ik, W):
            if self.kind != "kick_front":
                return W
            return (W + quat_rotate(quat_multiply(ik.q_lower_world, ankle_q[None]), toe[None]))[0]

        def pole_fn(d):
            return self.kick_pole(d[None], math.atan2(d[0], d[2]))[0]

        return self.aim(limb, S, pole_fn, end_fn, self.flex_hit)

    def kick_flight(self, limb: Limb, hip: np.ndarray, hit: dict):
        """Ankle target, pole and ankle rotation of the kicking leg in flight (hip-relative design)."""
        f_l, f_c, f_h, f_r, f_d = self.kick_keys
        sg, ch = self.sg, self.chamber
        ga = self.legs[self.hit_side].ground_ankle
        il, idd = int(f_l), int(f_d)  # integer frames by construction
        rel_l = ga[il] - hip[il]
        rel_d = ga[idd] - hip[idd]
        az_h, el_h = hit["az"], hit["el"]
        if self.kind == "kick_front":
            te, fx = ch["thigh_el"], ch["flex"]
            # thigh raised to elevation te, shin folded back by fx: (forward, up) of the ankle
            p = limb.l1 * np.array([math.cos(te), math.sin(te)])
            p = p + limb.l2 * np.array([math.cos(te - fx), math.sin(te - fx)])
            fwd = np.array([math.sin(az_h), 0.0, math.cos(az_h)])
            rel_c = p[0] * fwd + p[1] * UNIT_Y
        elif self.kind == "kick_round":
            # knee up towards the target, shin folded back and nearly horizontal
            e = el_h - rad(10)
            fx = ch["flex"]
            rel_c = limb.l1 * spherical(ch["knee_az"], e) + limb.l2 * spherical(ch["knee_az"] + sg * fx, 0.3 * e)
        else:  # side kick: knee to the chest, heel towards the target
            rel_c = 0.42 * (limb.l1 + limb.l2) * spherical(az_h + sg * rad(10), el_h - rad(20))
        rel_r = rel_c * ch["re"]
        rel_h = hit["wrist"] - hip[self.hit_frame]
        keys = [(f_l, rel_l), (f_c, rel_c), (f_h, rel_h), (f_r, rel_r), (f_d, rel_d)]
        ez = ["smooth", "strike", "smooth", "smooth"]
        dirs = dir_track(self.t, keys, ez)
        radius = track(self.t, [(k, np.linalg.norm(v)) for k, v in keys], ez)
        # during the strike the knee flexion, not the hip-ankle distance, is eased: the knee
        # then slows down into the hit instead of snapping through its last degrees (near
        # full extension the distance hardly changes while the angle changes fast)
        flex = track(self.t, [(k, flexion_at(limb, np.linalg.norm(v))) for k, v in keys], ez)
        strike = (self.t > f_c) & (self.t < f_h)
        radius[strike] = np.sqrt(limb.l1**2 + limb.l2**2 + 2 * limb.l1 * limb.l2 * np.cos(flex[strike]))
        target = hip + radius[:, None] * dirs
        pole = self.kick_pole(dirs, az_h)
        design = axis_angle_quat(UNIT_X, np.full(self.F, rad(self.ankle_design)))
        return target, pole, design


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """Half-open ``[start, stop)`` frame ranges where ``mask`` is true."""
    m = np.concatenate([[False], mask, [False]]).astype(int)
    d = np.diff(m)
    return [(int(a), int(b)) for a, b in zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1))]


def _replace(m: Motion, **kw) -> Motion:
    return dataclasses.replace(m, **kw)


# ---------------------------------------------------------------- public API: one clip
def _check_choice(name: str, value, allowed) -> str:
    return as_choice(value, name, allowed, error=MotionError)


def _seed(seed):
    """A seed for numpy: an int >= 0 or a non-empty sequence of them, else :class:`MotionError`."""
    if isinstance(seed, (list, tuple, np.ndarray)):
        s = as_real_array(seed, "seed", error=MotionError, integer=True, ndim=1)
        if s.size == 0 or s.min() < 0:
            raise MotionError(f"seed must be an int >= 0 or a non-empty sequence of them, got {describe(seed)}")
        return [int(x) for x in s]
    return as_int(seed, "seed", 0, None, error=MotionError)


def synthetic_clip(
    kind: str,
    side: str = "right",
    level: str = "middle",
    actor_height: float = REFERENCE_HEIGHT_M,
    seed: int | Sequence[int] | np.random.Generator = 0,
    fps: float = DEFAULT_FPS,
) -> tuple[Motion, dict]:
    """Generate one synthetic kung-fu clip and its annotation.

    Parameters
    ----------
    kind : {"punch", "kick_front", "kick_side", "kick_round", "stance"}
        A straight punch with the rear hand from a fist chambered at the hip (with hip
        and shoulder rotation and a small lunge); a front kick (ball of the foot), a
        side kick (heel, the body turned sideways and leaning away) or a round kick
        (instep, the body turning over the support foot), each with the rear leg from
        a knee chamber; or an idle fighting stance (small weight shifts and sway).
    side : {"left", "right"}, default "right"
        The striking hand or foot.  The actor stands with the other foot forward; for
        ``"stance"``, the side held back.
    level : {"high", "middle", "low"}, default "middle"
        Target height of the hit point (:data:`TARGET_HEIGHT_FRACTION`); ignored for
        ``"stance"`` (annotated ``"none"``).
    actor_height : float, default 1.75
        Actor height in metres; the skeleton is :func:`synthetic_skeleton`.
    seed : int, sequence of int or numpy.random.Generator, default 0
        Seed of the per-clip variations (timing, stance width and orientation, guard,
        amplitudes, target height jitter, hit flexion).  Equal seeds give equal clips.
    fps : float, default 60
        Frame rate, in [24, 240].

    Returns
    -------
    motion : Motion
        The clip in metres (``unit_m = 1``), Y up, the opponent towards +Z.
    annotation : dict
        ``kind``, ``semantics`` ("punch", "kick" or "other"), ``side``, ``level``,
        ``hit_joint`` (e.g. ``"RightHand"``; ``""`` for stance), ``hit_point``
        (``"end_site"``: the End Site of ``hit_joint``, ``"joint"``: the joint itself;
        ``""`` for stance), ``hit_frame`` (-1 for stance), ``hit_time`` (s),
        ``hit_position`` (world position of the hit point at the hit frame, m),
        ``target_height_m`` (the designed height), ``actor_height_m``, ``fps``,
        ``frame_time``, ``frames``, ``support_foot`` (joint name of the foot planted
        for the whole clip, for kicks), ``contacts`` (half-open frame ranges
        ``[start, stop)``: under ``"LeftFoot"``/``"RightFoot"`` the frames where that
        foot is flat and fixed, under ``"LeftToeBase"``/``"RightToeBase"`` those where
        the ball of the foot is fixed on the ground, flat or heel raised), ``phases``
        (frame of each key of the timeline) and ``flexion_at_hit_deg`` (elbow or knee
        flexion of the striking limb at the hit).

    Raises
    ------
    repro.errors.MotionError
        For an unknown kind, side or level, an actor height outside (0.5, 3] m or a
        frame rate outside [24, 240]; or (an internal error) if a planted foot or the
        hit could not be reached.
    """
    _check_choice("kind", kind, KINDS)
    _check_choice("side", side, SIDES)
    if kind != "stance":
        _check_choice("level", level, HIT_LEVELS)
    fps = as_real(fps, "fps", lo=24.0, hi=240.0, error=MotionError)
    scale_of(actor_height)
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(_seed(seed))
    b = _Builder(kind, side, level if kind != "stance" else "none", actor_height, rng, fps)
    if kind == "punch":
        b.design_punch()
    elif kind == "stance":
        b.design_stance()
    else:
        b.design_kick()
    motion, _ = b.solve()
    motion = _replace(motion, source=f"synthetic:{kind}:{side}:{b.level}:{float(actor_height):g}m")
    return motion, _annotation(b, motion, kind, side, fps, actor_height)


def _annotation(b: _Builder, motion: Motion, kind: str, side: str, fps: float, actor_height: float) -> dict:
    """The annotation :func:`synthetic_clip` returns (see its docstring)."""
    ann = {
        "kind": kind,
        "semantics": KIND_SEMANTICS[kind],
        "side": side,
        "level": b.level,
        "hit_joint": "",
        "hit_point": "",
        "hit_frame": -1,
        "hit_time": None,
        "hit_position": None,
        "target_height_m": None,
        "actor_height_m": float(actor_height),
        "fps": fps,
        "frame_time": motion.frame_time,
        "frames": motion.n_frames,
        "support_foot": None,
        "contacts": b.contacts,
        "phases": {k: float(v) for k, v in b.phases.items()},
        "flexion_at_hit_deg": None,
    }
    if kind != "stance":
        suffix, where = HIT_POINTS[kind]
        joint = b.hit_side + suffix
        h = b.hit_frame
        ann.update(
            hit_joint=joint,
            hit_point=where,
            hit_frame=h,
            hit_time=h * motion.frame_time,
            hit_position=tuple(float(x) for x in hit_point_trajectory(motion, joint, where)[h]),
            target_height_m=float(b.target_height),
            flexion_at_hit_deg=float(np.degrees(b.flex_hit)),
        )
        if kind != "punch":
            ann["support_foot"] = b.lead_side + "Foot"
    return ann
