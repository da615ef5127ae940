"""Joint-name tables of the three skeleton conventions and their expected roles (shared by
tests/motion/body/test_roles.py and tests/motion/body/test_skeleton.py)."""

CMU_NAMES = (
    "root lhipjoint lfemur ltibia lfoot ltoes rhipjoint rfemur rtibia rfoot rtoes lowerback upperback "
    "thorax lowerneck upperneck head lclavicle lhumerus lradius lwrist lhand lfingers lthumb rclavicle "
    "rhumerus rradius rwrist rhand rfingers rthumb"
).split()
CMU_PARENTS = [-1, 0, 1, 2, 3, 4, 0, 6, 7, 8, 9, 0, 11, 12, 13, 14, 15, 13, 17, 18, 19, 20, 21, 20, 13, 24, 25, 26, 27, 28, 27]
BANDAI_NAMES = (
    "joint_Root Hips Spine Chest Neck Head Shoulder_L UpperArm_L LowerArm_L Hand_L Shoulder_R UpperArm_R "
    "LowerArm_R Hand_R UpperLeg_L LowerLeg_L Foot_L Toes_L UpperLeg_R LowerLeg_R Foot_R Toes_R"
).split()
BANDAI_PARENTS = [-1, 0, 1, 2, 3, 4, 3, 6, 7, 8, 3, 10, 11, 12, 1, 14, 15, 16, 1, 18, 19, 20]

# Mixamo / cgspeed style (the synthetic kung-fu database's naming), T-pose, metres, Y up,
# facing +Z, the character's left on +X.
from tests.motion_fixtures import MIXAMO, MIXAMO_NAMES  # noqa: E402
MIXAMO_PARENTS = [-1 if p is None else MIXAMO_NAMES.index(p) for _, p, _ in MIXAMO]

CMU_EXPECTED = {
    "pelvis": "root", "spine": "lowerback", "chest": "thorax", "neck": "lowerneck", "head": "head",
    "left_clavicle": "lclavicle", "left_shoulder": "lhumerus", "left_elbow": "lradius",
    "left_wrist": "lwrist", "left_hand": "lhand", "left_hip": "lfemur", "left_knee": "ltibia",
    "left_ankle": "lfoot", "left_toe": "ltoes", "left_fist": "lhand", "left_foot": "ltoes",
    "right_clavicle": "rclavicle", "right_shoulder": "rhumerus", "right_elbow": "rradius",
    "right_wrist": "rwrist", "right_hand": "rhand", "right_hip": "rfemur", "right_knee": "rtibia",
    "right_ankle": "rfoot", "right_toe": "rtoes", "right_fist": "rhand", "right_foot": "rtoes",
}  # fmt: skip
BANDAI_EXPECTED = {
    "pelvis": "Hips", "spine": "Spine", "chest": "Chest", "neck": "Neck", "head": "Head",
    "left_clavicle": "Shoulder_L", "left_shoulder": "UpperArm_L", "left_elbow": "LowerArm_L",
    "left_wrist": "Hand_L", "left_hip": "UpperLeg_L", "left_knee": "LowerLeg_L", "left_ankle": "Foot_L",
    "left_toe": "Toes_L", "left_fist": "Hand_L", "left_foot": "Toes_L",
    "right_clavicle": "Shoulder_R", "right_shoulder": "UpperArm_R", "right_elbow": "LowerArm_R",
    "right_wrist": "Hand_R", "right_hip": "UpperLeg_R", "right_knee": "LowerLeg_R", "right_ankle": "Foot_R",
    "right_toe": "Toes_R", "right_fist": "Hand_R", "right_foot": "Toes_R",
}  # fmt: skip
MIXAMO_EXPECTED = {
    "pelvis": "Hips", "spine": "Spine", "chest": "Spine1", "neck": "Neck", "head": "Head",
    "left_clavicle": "LeftShoulder", "left_shoulder": "LeftArm", "left_elbow": "LeftForeArm",
    "left_wrist": "LeftHand", "left_hip": "LeftUpLeg", "left_knee": "LeftLeg", "left_ankle": "LeftFoot",
    "left_toe": "LeftToeBase", "left_fist": "LeftHand", "left_foot": "LeftToeBase",
    "right_clavicle": "RightShoulder", "right_shoulder": "RightArm", "right_elbow": "RightForeArm",
    "right_wrist": "RightHand", "right_hip": "RightUpLeg", "right_knee": "RightLeg", "right_ankle": "RightFoot",
    "right_toe": "RightToeBase", "right_fist": "RightHand", "right_foot": "RightToeBase",
}  # fmt: skip

