"""The InterLevel and InterScene reward / termination functions against hand computations.

Every expected value here is written from the equations (InterLevel, Eq. 1-9; InterScene's
2-D navigation reward as ``stairenv.tasks.interscene`` states it) with ``math``: the package's
helpers are only the functions under test.
"""

from __future__ import annotations

import math

import gymnasium as gym
import mujoco
import numpy as np
import pytest

import stairenv  # noqa: F401  (registers the envs)
from stairenv.tasks import interlevel as il
from stairenv.tasks.interscene import interscene_reward, interscene_reward_terms
from stairenv.humanoid.state import HumanoidState, read_state

SQRT_2PI = math.sqrt(2.0 * math.pi)
STANDING = 0.885  # root height of the standing character (design of the markers)
REL = 1e-12


def normal_pdf(x: float, mu: float, sigma: float) -> float:
    """Eq. (2)."""
    return math.exp(-((x - mu) ** 2) / (2.0 * sigma**2)) / (sigma * SQRT_2PI)


def threshold_gauss(x: float, mu: float, s1: float, s2: float, w_scale: float) -> float:
    """Eq. (3): s1 while the target is ahead (mu - x >= 0), w_scale G(s2) past it."""
    return normal_pdf(x, mu, s1) if mu - x >= 0.0 else w_scale * normal_pdf(x, mu, s2)


def arr(*values: float) -> np.ndarray:
    return np.array(values, dtype=float)


def rows(*points) -> np.ndarray:
    return np.array(points, dtype=float).reshape(len(points), -1)


# --- Eq. (2): Gaussian ----------------------------------------------------------------
@pytest.mark.parametrize("sigma", [0.25, 0.5, 1.0, 2.0])
def test_gaussian_peak_is_normal_density_at_mu(sigma):
    assert il.gaussian(1.3, 1.3, sigma) == pytest.approx(1.0 / (sigma * math.sqrt(2.0 * math.pi)), rel=REL)


@pytest.mark.parametrize("x, mu, sigma", [(0.0, 1.0, 0.5), (2.5, -1.0, 2.0), (-0.3, 0.2, 0.1), (4.0, 4.5, 3.0)])
def test_gaussian_matches_normal_density(x, mu, sigma):
    assert il.gaussian(x, mu, sigma) == pytest.approx(normal_pdf(x, mu, sigma), rel=REL)


def test_gaussian_one_sigma_ratio_and_array_input():
    # One standard deviation away the density is exp(-1/2) of the peak.
    sigma = 0.7
    assert il.gaussian(2.7, 2.0, sigma) / il.gaussian(2.0, 2.0, sigma) == pytest.approx(math.exp(-0.5), rel=1e-12)
    x = arr(-1.0, 0.0, 0.5, 3.0)
    expected = [normal_pdf(v, 0.5, 1.5) for v in x]
    np.testing.assert_allclose(il.gaussian(x, 0.5, 1.5), expected, rtol=1e-12)


# --- Eq. (3): threshold Gaussian ------------------------------------------------------
def test_equal_peak_scale_is_sigma_ratio():
    assert il.equal_peak_scale(2.0, 0.5) == pytest.approx(0.25, rel=REL)
    assert il.equal_peak_scale(1.5, 0.3) == pytest.approx(0.2, rel=REL)


def test_threshold_gaussian_branches():
    s1, s2, w = 2.0, 0.5, 0.3
    mu = 4.0
    # target ahead: sigma_before; exactly at mu counts as "ahead" (distance >= 0)
    x = arr(1.0, 3.9, 4.0, 4.1, 5.0)
    mus = np.full(5, mu)
    got = il.threshold_gaussian(x, mus, s1, s2, w)
    expected = [
        normal_pdf(1.0, mu, s1),
        normal_pdf(3.9, mu, s1),
        1.0 / (s1 * SQRT_2PI),
        w * normal_pdf(4.1, mu, s2),
        w * normal_pdf(5.0, mu, s2),
    ]
    np.testing.assert_allclose(got, expected, rtol=1e-12)


def test_threshold_gaussian_per_row_mu():
    x = arr(0.0, 0.0, 0.0)
    mu = arr(1.0, -1.0, 0.0)
    got = il.threshold_gaussian(x, mu, 1.0, 0.25, 0.5)
    expected = [normal_pdf(0, 1, 1.0), 0.5 * normal_pdf(0, -1, 0.25), 1.0 / SQRT_2PI]
    np.testing.assert_allclose(got, expected, rtol=1e-12)


@pytest.mark.parametrize("s1, s2", [(2.0, 0.5), (1.0, 0.3), (0.4, 1.2)])
def test_threshold_gaussian_equal_peaks_and_continuity(s1, s2):
    w = il.equal_peak_scale(s1, s2)
    mu = 2.0
    peak_before = il.threshold_gaussian(arr(mu), arr(mu), s1, s2, w)[0]
    # the peak of the "past" branch, w * G(mu; s2), computed by hand
    assert peak_before == pytest.approx(1.0 / (s1 * SQRT_2PI), rel=REL)
    assert w / (s2 * SQRT_2PI) == pytest.approx(peak_before, rel=1e-12)
    eps = 1e-7
    just_before = il.threshold_gaussian(arr(mu - eps), arr(mu), s1, s2, w)[0]
    just_after = il.threshold_gaussian(arr(mu + eps), arr(mu), s1, s2, w)[0]
    assert just_before == pytest.approx(just_after, rel=1e-9)
    assert just_after == pytest.approx(w * normal_pdf(mu + eps, mu, s2), rel=1e-12)
    # and the maximum is at the target: both sides are lower
    assert il.threshold_gaussian(arr(mu - 0.3, mu + 0.3), arr(mu, mu), s1, s2, w).max() < peak_before


def test_threshold_gaussian_without_equal_peaks_jumps():
    # With w_scale = 1 and a smaller sigma past the target, the peak past it is higher (the
    # reason the paper scales it): this guards that w_scale really multiplies the second branch.
    after = il.threshold_gaussian(arr(2.0 + 1e-9), arr(2.0), 2.0, 0.5, 1.0)[0]
    assert after == pytest.approx(1.0 / (0.5 * SQRT_2PI), rel=1e-9)


# --- height progress, Eq. (4) factor ----------------------------------------------------
def test_height_progress_relu_not_clipped():
    bottom, top = 0.885, 0.885 + 0.6
    z = arr(0.5, bottom, bottom + 0.3, top, top + 0.3)
    got = il.height_progress(z, np.full(5, bottom), np.full(5, top))
    np.testing.assert_allclose(got, [0.0, 0.0, 0.5, 1.0, 1.5], rtol=1e-12, atol=1e-15)


def test_progress_is_clipped_to_unit_interval():
    bottom = rows([0.0, 0.0, 0.885])
    target = rows([3.0, 0.0, 1.485])
    roots = rows([0, 0, 0.2], [0, 0, 1.185], [0, 0, 1.485], [0, 0, 2.5])
    got = il.progress(roots, np.repeat(bottom, 4, 0), np.repeat(target, 4, 0))
    np.testing.assert_allclose(got, [0.0, 0.5, 1.0, 1.0], rtol=1e-12, atol=1e-15)


# --- Eq. (4) and (9): location reward ----------------------------------------------------
def test_location_reward_3d_and_2d():
    s1, s2, s3 = 2.0, 0.5, 0.5
    w = s2 / s1
    target = rows([3.0, 0.0, 0.885 + 0.8])
    bottom = rows([0.0, 0.0, 0.885])
    cases = [
        [1.0, 0.2, 0.885 + 0.2],   # on the stairs, before M_T, a quarter of the way up
        [3.4, -0.3, 0.885 + 0.8],  # past M_T on the landing
        [-1.0, 0.0, 0.885],        # at the bottom: no height progress
        [1.5, 0.1, 0.7],           # below M_B (crouching): ReLU clamps to 0
    ]
    root = rows(*cases)
    T = np.repeat(target, 4, 0)
    B = np.repeat(bottom, 4, 0)
    got3 = il.location_reward(root, T, B, s1, s2, s3, w, True)
    got2 = il.location_reward(root, T, B, s1, s2, s3, w, False)
    for k, (u, wv, z) in enumerate(cases):
        tg = threshold_gauss(u, 3.0, s1, s2, w)
        across = normal_pdf(wv, 0.0, s3)
        prog = max((z - 0.885) / 0.8, 0.0)
        assert got3[k] == pytest.approx(tg * across * prog, rel=1e-12, abs=1e-15)
        assert got2[k] == pytest.approx(tg * across, rel=1e-12)
    # The InterLevel-2D ablation rewards standing at the bottom; InterLevel does not.
    assert got3[2] == 0.0
    assert got2[2] > 0.0


def test_location_reward_peaks_at_target():
    s1, s2, s3 = 2.0, 0.5, 0.5
    target = rows([3.0, 0.0, 1.685])
    bottom = rows([0.0, 0.0, 0.885])
    at = il.location_reward(target.copy(), target, bottom, s1, s2, s3, s2 / s1, True)[0]
    assert at == pytest.approx(1.0 / (s1 * SQRT_2PI) / (s3 * SQRT_2PI), rel=1e-12)


# --- Eq. (5)-(6): facing ---------------------------------------------------------------
@pytest.mark.parametrize(
    "heading, expected",
    [
        ((1.0, 0.0), 1.0),                                   # facing the target
        ((0.0, 1.0), 0.0),                                   # perpendicular
        ((0.0, -3.0), 0.0),                                  # perpendicular, the other way
        ((-1.0, 0.0), 0.0),                                  # facing away: ReLU, no penalty
        ((math.cos(math.pi / 4), math.sin(math.pi / 4)), math.cos(math.pi / 4)),
        ((5.0, 5.0), math.cos(math.pi / 4)),                 # heading length is irrelevant
        ((0.01, 0.0), 1.0),
        ((math.cos(2.0), math.sin(2.0)), 0.0),               # 115 deg away
        ((math.cos(1.0), -math.sin(1.0)), math.cos(1.0)),
    ],
)
def test_facing_reward(heading, expected):
    root = rows([1.0, 2.0, 0.9])
    target = rows([4.0, 2.0, 1.7])  # due +x of the root (heights ignored)
    got = il.facing_reward(rows(heading), root, target)[0]
    # the kernel divides by |F_tar| |F_cur| + 1e-9: allow that relative slack
    assert got == pytest.approx(expected, rel=1e-6, abs=1e-8)


def test_facing_reward_target_direction_rotated():
    # target at 135 deg from the root; heading at 90 deg -> cos 45 deg
    root = rows([0.0, 0.0, 0.9], [0.0, 0.0, 0.9])
    target = rows([-2.0, 2.0, 0.0], [-2.0, 2.0, 5.0])
    got = il.facing_reward(rows([0.0, 1.0], [0.0, 7.0]), root, target)
    np.testing.assert_allclose(got, [math.cos(math.pi / 4)] * 2, rtol=1e-8)


# --- Eq. (7)-(8): velocity ----------------------------------------------------------------
def test_speed_towards_projects_on_3d_direction():
    dt = 1.0 / 30.0
    prev = rows([0.0, 0.0, 1.0], [1.0, 1.0, 0.9])
    target = rows([3.0, 0.0, 5.0], [1.0, 4.0, 0.9])
    root = rows([0.06, 0.02, 1.03], [1.01, 1.05, 0.95])
    got = il.speed_towards(prev, root, target, dt)
    expected = []
    for p0, p1, t in zip(prev, root, target):
        d = [t[i] - p0[i] for i in range(3)]
        norm = math.sqrt(sum(c * c for c in d))
        expected.append(sum((p1[i] - p0[i]) * d[i] for i in range(3)) / norm / dt)
    np.testing.assert_allclose(got, expected, rtol=1e-7)
    # second row: straight towards the target along +y at 0.05 m per step = 1.5 m/s
    assert got[1] == pytest.approx(1.5, rel=1e-7)


def test_speed_towards_moving_away_is_negative():
    got = il.speed_towards(rows([0, 0, 0]), rows([-0.1, 0, 0]), rows([2, 0, 0]), 0.1)[0]
    assert got == pytest.approx(-1.0, rel=1e-7)


def test_velocity_reward():
    target_speed = 1.0
    speeds = arr(2.0, 1.0, 0.5, 0.0, -1.0)
    got = il.velocity_reward(speeds, target_speed)
    expected = [1.0, 1.0, math.exp(-2.0 * 0.25), math.exp(-2.0), math.exp(-8.0)]
    np.testing.assert_allclose(got, expected, rtol=1e-12)


# --- frames -----------------------------------------------------------------------------
def test_to_stairs_frame_rotated():
    yaw = 2.3
    c, s = math.cos(yaw), math.sin(yaw)
    rotation = np.array([[[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]])  # columns u, w, z
    origin = rows([1.5, -0.5, 0.0])
    points = rows([1.5 + 2.0 * c, -0.5 + 2.0 * s, 0.3])  # two metres up the ascent axis
    np.testing.assert_allclose(il.to_stairs_frame(points, origin, rotation), [[2.0, 0.0, 0.3]], atol=1e-12)
    p = [0.2, 3.0, 1.1]
    dx, dy = p[0] - 1.5, p[1] + 0.5
    expected = [[c * dx + s * dy, -s * dx + c * dy, 1.1]]
    np.testing.assert_allclose(il.to_stairs_frame(rows(p), origin, rotation), expected, atol=1e-12)
    # w is to the left of the ascent
    left = rows([1.5 - s, -0.5 + c, 0.0])
    np.testing.assert_allclose(il.to_stairs_frame(left, origin, rotation), [[0.0, 1.0, 0.0]], atol=1e-12)


# --- the whole Eq. (1) on a HumanoidState -------------------------------------------------
@pytest.fixture(scope="module")
def env_state():
    env = gym.make("InterLevel-v0").unwrapped
    env.reset(seed=0)
    st = read_state(env.data, env._idx)
    st = HumanoidState(*(np.array(a, copy=True) for a in st))
    stairs = env.stairs
    dt = env.dt
    env.close()
    return st, env._goal, stairs, dt


def _with_root(state: HumanoidState, root, heading_yaw: float) -> HumanoidState:
    body_pos = state.body_pos.copy()
    body_mat = state.body_mat.copy()
    body_pos[0, 0] = root
    c, s = math.cos(heading_yaw), math.sin(heading_yaw)
    # pelvis pitched 0.2 rad forward then yawed: the heading is the x axis projected on the ground
    cp, sp = math.cos(0.2), math.sin(0.2)
    pitch = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    yaw = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    body_mat[0, 0] = yaw @ pitch
    return state._replace(body_pos=body_pos, body_mat=body_mat)


def _hand_terms(stairs, root, prev, heading_yaw, dt, cfg):
    """Eq. (1)-(8) by hand for one root position (world)."""
    n, h, d, L = stairs.num_steps, stairs.step_height, stairs.step_depth, stairs.landing_depth
    cy, sy = math.cos(stairs.yaw), math.sin(stairs.yaw)
    ox, oy = stairs.distance * cy, stairs.distance * sy
    # stairs frame of the root
    u = (root[0] - ox) * cy + (root[1] - oy) * sy
    w = -(root[0] - ox) * sy + (root[1] - oy) * cy
    z = root[2]
    t_u, t_z, b_z = (n - 1) * d + L / 2.0, n * h + STANDING, STANDING
    s1, s2, s3 = cfg["sigma_before"], cfg["sigma_after"], cfg["sigma_across"]
    w_scale = s2 / s1
    loc = threshold_gauss(u, t_u, s1, s2, w_scale) * normal_pdf(w, 0.0, s3)
    if cfg["progress_scaling"]:
        loc *= max((z - b_z) / (t_z - b_z), 0.0)
    # M_T in the world
    tx, ty = ox + t_u * cy, oy + t_u * sy
    fx, fy = tx - root[0], ty - root[1]
    nf = math.hypot(fx, fy)
    face = max((math.cos(heading_yaw) * fx + math.sin(heading_yaw) * fy) / nf, 0.0)
    dvec = [tx - prev[0], ty - prev[1], t_z - prev[2]]
    nd = math.sqrt(sum(c * c for c in dvec))
    speed = sum((root[i] - prev[i]) * dvec[i] for i in range(3)) / nd / dt
    vel = math.exp(-2.0 * max(cfg["target_speed"] - speed, 0.0) ** 2)
    return [cfg["w_location"] * loc, cfg["w_facing"] * face, cfg["w_velocity"] * vel]


def _world(stairs, u, w, z):
    cy, sy = math.cos(stairs.yaw), math.sin(stairs.yaw)
    return [(stairs.distance + u) * cy - w * sy, (stairs.distance + u) * sy + w * cy, z]


REWARD_CASES = [
    # (u, w, z) of the root in the stairs frame, heading relative to the ascent, prev offset (world)
    ((0.4, 0.15, STANDING + 0.1), 0.3, (-0.02, -0.01, -0.005)),
    ((-1.0, -0.3, STANDING - 0.05), -2.5, (0.01, 0.03, 0.0)),
    ("past", 0.0, (-0.03, 0.0, 0.0)),
]

CONFIGS = [
    dict(w_location=3.0, w_facing=0.1, w_velocity=0.4, sigma_before=2.0, sigma_after=0.5, sigma_across=0.5,
         target_speed=1.0, progress_scaling=True),
    dict(w_location=1.5, w_facing=0.7, w_velocity=2.0, sigma_before=1.0, sigma_after=0.3, sigma_across=0.8,
         target_speed=0.4, progress_scaling=False),
]


def _case_points(stairs, case):
    (local, rel_yaw, prev_off) = case
    if local == "past":  # on the landing, 0.4 m beyond M_T
        t_u = (stairs.num_steps - 1) * stairs.step_depth + stairs.landing_depth / 2.0
        local = (t_u + 0.4, 0.05, stairs.num_steps * stairs.step_height + STANDING)
    root = _world(stairs, *local)
    prev = [root[i] + prev_off[i] for i in range(3)]
    return root, prev, stairs.yaw + rel_yaw


@pytest.mark.parametrize("cfg", CONFIGS, ids=["default", "custom-2d"])
@pytest.mark.parametrize("case", REWARD_CASES, ids=["on-stairs", "before-stairs", "past-target"])
def test_interlevel_reward_terms_match_hand(env_state, cfg, case):
    state, goal, stairs, dt = env_state
    root, prev, heading = _case_points(stairs, case)
    st = _with_root(state, root, heading)
    got = il.interlevel_reward_terms(st, rows(prev), goal, il.InterLevelReward(**cfg), dt)
    assert got.shape == (1, 3)
    expected = _hand_terms(stairs, root, prev, heading, dt, cfg)
    # (the kernels guard divisions with + 1e-9, hence rtol 1e-6 rather than machine precision)
    np.testing.assert_allclose(got[0], expected, rtol=1e-6, atol=1e-14)
    assert got[0].sum() == pytest.approx(sum(expected), rel=1e-6)


def test_interlevel_reward_terms_batch_equals_rows(env_state):
    state, goal, stairs, dt = env_state
    cfg = il.InterLevelReward()
    singles, states, prevs = [], [], []
    for case in REWARD_CASES:
        root, prev, heading = _case_points(stairs, case)
        st = _with_root(state, root, heading)
        states.append(st)
        prevs.append(prev)
        singles.append(il.interlevel_reward_terms(st, rows(prev), goal, cfg, dt)[0])
    batch = HumanoidState(*(np.concatenate(f, axis=0) for f in zip(*states)))
    goal3 = il.StairsGoal(*(np.concatenate([g] * 3, axis=0) for g in goal))
    got = il.interlevel_reward_terms(batch, rows(*prevs), goal3, cfg, dt)
    assert got.shape == (3, 3)
    np.testing.assert_allclose(got, np.stack(singles), rtol=1e-13, atol=0)
    # rows are really different (the test would be vacuous otherwise)
    assert not np.allclose(got[0], got[1])


def test_stairs_goal_from_stairs(env_state):
    _, goal, stairs, _ = env_state
    n, h, d, L = stairs.num_steps, stairs.step_height, stairs.step_depth, stairs.landing_depth
    np.testing.assert_allclose(goal.target[0], _world(stairs, (n - 1) * d + L / 2, 0.0, n * h + STANDING), atol=1e-12)
    np.testing.assert_allclose(goal.bottom[0], _world(stairs, 0.0, 0.0, STANDING), atol=1e-12)
    assert goal.top_height[0] == pytest.approx(n * h, rel=1e-12)
    expected_dist = math.hypot((n - 1) * d + L / 2, n * h)
    assert goal.marker_distance[0] == pytest.approx(expected_dist, rel=1e-12)


# --- InterLevelReward validation ----------------------------------------------------------
@pytest.mark.parametrize(
    "kwargs, name",
    [
        (dict(w_location=-1.0), "w_location"),
        (dict(w_facing=-0.1), "w_facing"),
        (dict(w_velocity=-2.0), "w_velocity"),
        (dict(sigma_before=0.0), "sigma_before"),
        (dict(sigma_after=-0.5), "sigma_after"),
        (dict(sigma_across=0.0), "sigma_across"),
        (dict(sigma_across=float("nan")), "sigma_across"),
        (dict(w_scale=-0.1), "w_scale"),
        (dict(target_speed=-1.0), "target_speed"),
        (dict(w_facing="a lot"), "w_facing"),
    ],
)
def test_interlevel_reward_validation(kwargs, name):
    with pytest.raises(ValueError, match=name):
        il.InterLevelReward(**kwargs)


def test_interlevel_reward_defaults():
    cfg = il.InterLevelReward(sigma_before=1.6, sigma_after=0.4)
    assert cfg.w_scale == pytest.approx(0.25, rel=REL)
    assert il.InterLevelReward(w_scale=0.7).w_scale == 0.7
    zero = il.InterLevelReward(w_location=0.0, w_facing=0.0, w_velocity=0.0)
    assert (zero.w_location, zero.w_facing, zero.w_velocity) == (0.0, 0.0, 0.0)


# --- termination and success ----------------------------------------------------------------
HEAD, PELVIS, RFOOT, LFOOT = 2, 0, 11, 14


def _upright() -> np.ndarray:
    pos = np.zeros((15, 3))
    pos[:, 2] = 0.9
    pos[PELVIS, 2] = 0.9
    pos[1, 2] = 1.14
    pos[HEAD, 2] = 1.36
    pos[[9, 12], 2] = 0.9
    pos[[10, 13], 2] = 0.48
    pos[[RFOOT, LFOOT], 2] = 0.07
    return pos


def test_has_fallen_cases():
    gap = 0.2
    upright = _upright()
    head_low = upright.copy()
    head_low[HEAD, 2] = 0.9  # head at hip height: lying down
    head_near = upright.copy()
    head_near[HEAD, 2] = 0.9 + 0.19
    head_ok = upright.copy()
    head_ok[HEAD, 2] = 0.9 + 0.21
    foot_up = upright.copy()
    foot_up[LFOOT, 2] = 0.9 - 0.1  # a foot lifted to within the gap of the hips
    right_foot_up = upright.copy()
    right_foot_up[RFOOT, 2] = 0.9 - 0.15
    foot_knee_high = upright.copy()
    foot_knee_high[RFOOT, 2] = 0.9 - 0.3  # a high step, still clear of the hips
    upside_down = upright.copy()
    upside_down[:, 2] = 2.0 - upright[:, 2]
    elevated = upright.copy()
    elevated[:, 2] += 1.5  # standing on a high landing: not a fall
    batch = np.stack([upright, head_low, head_near, head_ok, foot_up, right_foot_up, foot_knee_high,
                      upside_down, elevated])
    got = il.has_fallen(batch, gap)
    assert got.tolist() == [False, True, True, False, True, True, False, True, False]


def test_reached_top():
    target = rows([2.0, 1.0, 1.5])
    top = arr(0.6)
    radius = 0.5
    roots = [
        [2.0, 1.0, 1.45],  # at M_T, standing on the landing
        [2.3, 1.3, 1.45],  # 0.42 m away horizontally
        [2.4, 1.4, 1.45],  # 0.57 m away
        [2.0, 1.0, 1.05],  # right place, root 0.45 above the landing: not standing on it
        [2.0, 1.0, 1.15],  # 0.55 above: standing
    ]
    got = il.reached_top(rows(*roots), np.repeat(target, 5, 0), np.repeat(top, 5), radius)
    assert got.tolist() == [True, True, False, False, True]


# --- InterScene -------------------------------------------------------------------------------
def _interscene_by_hand(prev, root, heading, target, dt):
    dx, dy = target[0] - root[0], target[1] - root[1]
    d2 = dx * dx + dy * dy
    dist = math.sqrt(d2)
    ux, uy = dx / dist, dy / dist
    vx, vy = (root[0] - prev[0]) / dt, (root[1] - prev[1]) / dt
    hn = math.hypot(*heading)
    far = (0.5 * math.exp(-0.5 * d2)
           + 0.4 * math.exp(-2.0 * max(0.0, 1.5 - (vx * ux + vy * uy)) ** 2)
           + 0.1 * max(0.0, (heading[0] * ux + heading[1] * uy) / hn))
    if d2 < 0.5:
        far = 1.0
    near = math.exp(-10.0 * d2)
    return 0.7 * near, 0.3 * far


INTERSCENE_CASES = [
    # prev, root, heading, target
    ([0.0, 0.0, 0.9], [0.03, 0.01, 0.9], [1.0, 0.2], [3.0, 1.0, 1.6]),         # far, walking towards
    ([1.0, 1.0, 0.9], [0.98, 1.0, 0.9], [-2.0, 0.0], [-1.0, 1.0, 2.2]),        # far, heading along, slow
    ([0.0, 0.0, 0.9], [0.0, 0.0, 0.9], [0.0, -1.0], [0.72, 0.1, 0.9]),         # d2 = 0.528 -> far formula
    ([0.0, 0.0, 0.9], [0.0, 0.0, 0.9], [0.0, -1.0], [0.69, 0.1, 0.9]),         # d2 = 0.4861 < 0.5 -> far = 1
    ([0.0, 0.0, 0.9], [0.01, 0.0, 0.9], [-1.0, 0.0], [0.71, 0.1, 0.9]),        # d2 just above 0.5
    ([2.0, 0.0, 0.9], [2.0, 0.0, 0.9], [1.0, 0.0], [2.1, 0.05, 0.9]),           # near the target
]


@pytest.mark.parametrize("prev, root, heading, target", INTERSCENE_CASES)
def test_interscene_reward_by_hand(prev, root, heading, target):
    dt = 1.0 / 30.0
    near, far = interscene_reward(rows(prev), rows(root), rows(heading), rows(target), dt)
    e_near, e_far = _interscene_by_hand(prev, root, heading, target, dt)
    assert near[0] == pytest.approx(e_near, rel=1e-12)
    assert far[0] == pytest.approx(e_far, rel=1e-12)


def test_interscene_far_switch():
    dt = 1.0 / 30.0
    # standing still, facing away: the far formula gives 0.5 e^{-d2/2} + 0.4 e^{-4.5} well below 1
    prev = root = rows([0.0, 0.0, 0.9], [0.0, 0.0, 0.9])
    heading = rows([-1.0, 0.0], [-1.0, 0.0])
    target = rows([math.sqrt(0.49), 0.0, 0.9], [math.sqrt(0.51), 0.0, 0.9])
    _, far = interscene_reward(prev, root, heading, target, dt)
    assert far[0] == pytest.approx(0.3, rel=1e-12)
    expected = 0.3 * (0.5 * math.exp(-0.5 * 0.51) + 0.4 * math.exp(-2.0 * 1.5**2))
    assert far[1] == pytest.approx(expected, rel=1e-9)


def test_interscene_ignores_heights():
    dt = 1.0 / 30.0
    prev, root, heading, target = rows([0, 0, 0.9]), rows([0.04, 0.02, 0.9]), rows([1.0, 0.5]), rows([2.0, 0.5, 0.9])
    base = interscene_reward(prev, root, heading, target, dt)
    for dz_prev, dz_root, dz_target in [(0.0, 0.0, 3.0), (0.5, -0.3, 0.0), (-2.0, 1.0, 7.0)]:
        got = interscene_reward(prev + [0, 0, dz_prev], root + [0, 0, dz_root], heading,
                                target + [0, 0, dz_target], dt)
        np.testing.assert_allclose(got[0], base[0], rtol=1e-13)
        np.testing.assert_allclose(got[1], base[1], rtol=1e-13)


def test_interscene_reward_terms_on_state(env_state):
    state, goal, stairs, dt = env_state
    root = [0.3, -0.2, 0.9]
    prev = [0.28, -0.21, 0.95]
    st = _with_root(state, root, 0.4)
    got = interscene_reward_terms(st, rows(prev), goal.target, dt)
    expected = _interscene_by_hand(prev, root, [math.cos(0.4), math.sin(0.4)], goal.target[0].tolist(), dt)
    np.testing.assert_allclose(got[0], expected, rtol=1e-12)


# --- end to end through the env ---------------------------------------------------------------
def _reward_sum(info) -> float:
    return sum(v for k, v in info.items() if k.startswith("reward_"))


def _knock_over(env) -> None:
    """Put the character horizontal (rotated 90 deg about its y axis) in the air, at rest."""
    u = env.unwrapped
    qpos = u.data.qpos
    root = u._idx.qpos_root
    q = qpos[root].copy()
    q[2] = 1.0
    q[3:7] = [math.cos(math.pi / 4), 0.0, math.sin(math.pi / 4), 0.0]
    qpos[root] = q
    u.data.qvel[:] = 0.0
    mujoco.mj_forward(u.model, u.data)


@pytest.mark.parametrize(
    "env_id, terms",
    [
        ("InterLevel-v0", ("reward_location", "reward_facing", "reward_velocity")),
        ("InterLevel2D-v0", ("reward_location", "reward_facing", "reward_velocity")),
        ("InterSceneStairs-v0", ("reward_near", "reward_far")),
    ],
)
def test_env_reward_terms_sum_to_reward(env_id, terms):
    env = gym.make(env_id)
    env.reset(seed=3)
    rng = np.random.default_rng(0)
    nonzero = 0.0
    for _ in range(6):
        action = rng.uniform(-0.3, 0.3, 28)
        _, reward, terminated, _, info = env.step(action)
        for t in terms + ("reward_success", "reward_failure"):
            assert t in info
        assert set(k for k in info if k.startswith("reward_")) == set(terms) | {"reward_success", "reward_failure"}
        assert reward == pytest.approx(_reward_sum(info), rel=1e-12, abs=1e-15)
        assert not terminated
        nonzero += abs(reward)
    assert nonzero > 0.0

    # a fall: the task terms are replaced by the failure reward
    _knock_over(env)
    _, reward, terminated, truncated, info = env.step(np.zeros(28))
    assert info["fell"] is True
    assert terminated and not truncated
    assert info["reward_failure"] == -1.0
    assert all(info[t] == 0.0 for t in terms)
    assert reward == pytest.approx(_reward_sum(info), rel=1e-12)
    assert reward == pytest.approx(-1.0)
    env.close()


def test_env_step_reward_matches_hand_formula():
    """One env step: the reward terms equal Eq. (1)-(8) computed by hand from the state."""
    for env_id, progress_scaling in (("InterLevel-v0", True), ("InterLevel2D-v0", False)):
        env = gym.make(env_id, random_start_heading=False)  # facing the stairs: R_facing > 0
        env.reset(seed=5)
        u = env.unwrapped
        prev = u.data.xpos[u._idx.pelvis_id].copy()
        _, _, _, _, info = env.step(np.full(28, 0.1))
        root = u.data.xpos[u._idx.pelvis_id].copy()
        heading = math.atan2(u.data.xmat[u._idx.pelvis_id][3], u.data.xmat[u._idx.pelvis_id][0])
        cfg = dict(CONFIGS[0], progress_scaling=progress_scaling)
        expected = _hand_terms(u.stairs, root.tolist(), prev.tolist(), heading, u.dt, cfg)
        got = [info["reward_location"], info["reward_facing"], info["reward_velocity"]]
        np.testing.assert_allclose(got, expected, rtol=1e-6, atol=1e-14)
        assert got[1] > 0.05 and got[2] > 0.0
        # at the start the root is at M_B's height (standing on the floor; it may settle a few
        # micrometres up in the first step): 3-D location reward ~0, 2-D clearly positive
        assert (got[0] > 1e-3) == (not progress_scaling)
        env.close()


def test_step_reward_composes_terms_bonus_and_failure_by_hand():
    """``interlevel_reward_and_end``: the terms summed, plus the success bonus; a fall replaces the terms by
    the failure reward; neither counts at the episode's first outcome (step 0); the episode ends on a fall,
    or on success where success terminates."""
    terms = np.array([[0.3, 0.1, 0.4]] * 4)
    results = np.zeros((4, len(il.STEP_RESULTS)))
    fell, success = il.STEP_RESULTS.index("fell"), il.STEP_RESULTS.index("success")
    results[1, success] = 1.0
    results[2, fell] = 1.0
    results[3, fell] = results[3, success] = 1.0
    steps = np.array([5, 5, 5, 0])
    clocks = np.full(4, np.inf), np.zeros(4, dtype=np.int64)
    for terminate_on_success in (True, False):
        params = il.end_parameters(0.2, None, 1 / 30, 10.0, -2.0, terminate_on_success)
        reward, all_terms, flags = il.interlevel_reward_and_end(terms, results, steps, *clocks, params)
        assert reward.tolist() == [0.3 + 0.1 + 0.4, 0.3 + 0.1 + 0.4 + 10.0, -2.0, 0.3 + 0.1 + 0.4]
        assert all_terms.tolist() == [[0.3, 0.1, 0.4, 0.0, 0.0], [0.3, 0.1, 0.4, 10.0, 0.0],
                                      [0.0, 0.0, 0.0, 0.0, -2.0], [0.3, 0.1, 0.4, 0.0, 0.0]]
        fell_flags, success_flags, stalled, ended = flags.T.tolist()
        assert fell_flags == [False, False, True, False] and success_flags == [False, True, False, False]
        assert stalled == [False] * 4 and ended == [False, terminate_on_success, True, False]
