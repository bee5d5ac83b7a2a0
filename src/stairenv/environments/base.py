"""What every humanoid env shares: the model, the action map, stepping, style features, rendering."""

from __future__ import annotations

import os
import zipfile
from pathlib import Path

import gymnasium as gym
import mujoco
import numpy as np
from gymnasium import spaces

from stairenv.humanoid import NUM_DOFS, PD_GAINS, HumanoidIndices
from stairenv.motion.rsi import BUILTIN_REFERENCE_SETS, load_reference_library
from stairenv.rendering import RENDER_MODES, FollowCamera, HumanViewer
from stairenv.style.features import FeatureHistory
from stairenv.validation import check_choice, check_int

_BADQACC, _BADQVEL, _BADQPOS = (int(w) for w in (
    mujoco.mjtWarning.mjWARN_BADQACC, mujoco.mjtWarning.mjWARN_BADQVEL, mujoco.mjtWarning.mjWARN_BADQPOS))

# Speeds no body of this character reaches while the physics is sound. Saturated
# actions (bang-bang, clipped Gaussians) peak below ~90 rad/s at the joints and the
# root stays far below 20 m/s (benchmarks/bench_saturated.py); a state beyond these
# is a divergence on its way, flagged long before MuJoCo's own 1e10 check fires.
MAX_JOINT_SPEED = 250.0        # rad/s, every hinge and the root's angular velocity
MAX_ROOT_SPEED = 50.0          # m/s, the root's linear velocity


def check_humanoid_keywords(frame_skip, amp_history, render_mode, width, height,
                            pd_gains: str = "soft") -> tuple[int, int, str | None, int, int]:
    """The keywords every env hands to ``load_humanoid_spec`` and ``_setup``, checked; the envs call it
    first in ``__init__`` so that a bad value fails before any model is built."""
    check_choice("pd_gains", pd_gains, tuple(PD_GAINS))
    if render_mode is not None:
        check_choice("render_mode", render_mode, RENDER_MODES)
    return (check_int("frame_skip", frame_skip, 1, 100), check_int("amp_history", amp_history, 1, 100),
            render_mode, check_int("width", width, 16, 4096), check_int("height", height, 16, 4096))


def check_reference_motion(source) -> None:
    """``reference_motion``: None, a built-in set or an existing ``.npz`` clip or folder of them. Files are
    loaded now (``load_reference_library`` caches them), whatever ``init`` is, so that a bad file fails
    at construction and not when AMP or a reference start first needs it."""
    if source is None:
        return
    if not isinstance(source, (str, os.PathLike)):
        raise TypeError(f"reference_motion must be None, a path or one of {list(BUILTIN_REFERENCE_SETS)}, "
                        f"got {type(source).__name__}")
    if str(source) in BUILTIN_REFERENCE_SETS:
        return
    if not Path(source).exists():
        raise ValueError(f"reference_motion {str(source)!r} is neither one of {list(BUILTIN_REFERENCE_SETS)} "
                         "nor an existing .npz file or folder of them")
    try:
        load_reference_library(source)
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as error:
        raise ValueError(f"reference_motion {str(source)!r} could not be loaded: {error}") from error


class HumanoidEnv(gym.Env):
    """Base class: subclasses build a spec (humanoid + world), call ``_setup`` and implement the task.

    - actions (28,) in [-1, 1] become PD targets ``offset + scale * a`` (the range
      ``load_humanoid_spec`` wrote into the actuators' ctrlrange; MuJoCo clamps to it);
      wrong shapes and NaN/inf raise ``ValueError``;
    - ``_simulate`` steps the physics ``frame_skip`` times and reports divergence
      (MuJoCo resets the data, so the simulation time jumps back) or a speed no body
      reaches (``MAX_JOINT_SPEED``, ``MAX_ROOT_SPEED``), so that no huge state is observed;
    - ``self._amp`` keeps the last ``amp_history`` frames of style features;
    - ``step`` runs the subclass's ``_step`` and hands the step's ``info["amp_obs"]`` (and
      ``info["amp_condition"]`` if any) to the sink set by ``set_amp_sink``: the AMP wrappers
      score it on another core while the next envs step (``style.pipeline``);
    - ``render()`` follows the pelvis; subclasses may override ``_render_lines``.
    """

    metadata = {"render_modes": list(RENDER_MODES), "render_fps": 30}
    #: ``load_reference_library`` source used when ``reference_motion`` is None (RSI and AMP reference).
    DEFAULT_REFERENCE_MOTION: str | None = None

    def _setup(self, spec: mujoco.MjSpec, frame_skip: int, amp_history: int, render_mode: str | None,
               width: int, height: int) -> None:
        frame_skip, amp_history, render_mode, width, height = check_humanoid_keywords(
            frame_skip, amp_history, render_mode, width, height)
        self.frame_skip = frame_skip
        self._amp = FeatureHistory(amp_history)
        self.render_mode = render_mode
        self.width, self.height = width, height
        spec.visual.global_.offwidth = max(self.width, spec.visual.global_.offwidth)
        spec.visual.global_.offheight = max(self.height, spec.visual.global_.offheight)
        self.model = spec.compile()
        self.data = mujoco.MjData(self.model)
        self._idx = HumanoidIndices.from_model(self.model)
        low, high = self.model.actuator_ctrlrange.T.copy()
        self._ctrl_offset, self._ctrl_scale = 0.5 * (low + high), 0.5 * (high - low)
        self.dt = self.model.opt.timestep * self.frame_skip
        self.metadata = {**self.metadata, "render_fps": int(round(1.0 / self.dt))}
        self.action_space = spaces.Box(-1.0, 1.0, shape=(NUM_DOFS,), dtype=np.float32)
        self._needs_reset = True
        self._camera: FollowCamera | None = None
        self._viewer: HumanViewer | None = None
        self._camera_distance, self._camera_elevation, self._camera_azimuth = 4.5, -18.0, 135.0
        self._amp_sink = None

    def step(self, action):
        obs, reward, terminated, truncated, info = self._step(action)
        if self._amp_sink is not None:
            self._amp_sink(info["amp_obs"], info.get("amp_condition"))
        return obs, reward, terminated, truncated, info

    def _step(self, action):
        raise NotImplementedError

    def set_amp_sink(self, sink) -> None:
        """``sink(amp_obs, amp_condition_or_None)`` is called at the end of every ``step``
        (None: no sink). The AMP wrappers set it for in-process vec envs."""
        if sink is not None and not callable(sink):
            raise TypeError(f"sink must be callable or None, got {type(sink).__name__}")
        self._amp_sink = sink

    def _hold_pose_ctrl(self) -> None:
        """Servo targets = the current joint angles (an episode starts holding its pose)."""
        self.data.ctrl[:] = np.clip(self.data.qpos[self._idx.qpos_joints], *self.model.actuator_ctrlrange.T)

    def _simulate(self, action) -> bool:
        """Apply ``action`` for ``frame_skip`` physics steps; False if the physics diverged."""
        action = np.asarray(action, dtype=np.float64)
        if action.shape != (NUM_DOFS,):
            raise ValueError(f"action must have shape ({NUM_DOFS},), got {action.shape}")
        if not np.isfinite(action).all():
            bad = np.flatnonzero(~np.isfinite(action)).tolist()
            raise ValueError(f"action must be finite, got NaN or inf at indices {bad}")
        if self._needs_reset:
            raise gym.error.ResetNeeded("call reset() before step() (after an unstable-physics truncation too)")
        data = self.data
        data.ctrl[:] = self._ctrl_offset + self._ctrl_scale * action
        expected_time = data.time + self.frame_skip * self.model.opt.timestep
        mujoco.mj_step(self.model, data, self.frame_skip)
        # MuJoCo resets the data when positions, velocities or accelerations blow up:
        # the time jumps back and the warning counts (zeroed at every episode reset by
        # mj_resetData) go up. Otherwise qpos and qvel are finite by its checks.
        warnings = data.warning
        if (data.time < expected_time - 1e-9 or warnings[_BADQACC].number or warnings[_BADQVEL].number
                or warnings[_BADQPOS].number or not self._speeds_plausible()):
            self._needs_reset = True
            gym.logger.warn("physics became unstable; episode truncated (info['physics_unstable'] = True)")
            return False
        # mj_step leaves body poses at the start of its last substep: bring them up to qpos.
        mujoco.mj_kinematics(self.model, data)
        return True

    def _speeds_plausible(self) -> bool:
        """False once the character moves faster than its body can (``MAX_JOINT_SPEED``, ``MAX_ROOT_SPEED``)."""
        qvel = self.data.qvel
        root = qvel[self._idx.qvel_root]
        return bool(np.abs(root[:3]).max() <= MAX_ROOT_SPEED and np.abs(root[3:]).max() <= MAX_JOINT_SPEED
                    and np.abs(qvel[self._idx.qvel_joints]).max() <= MAX_JOINT_SPEED)

    # --- rendering ----------------------------------------------------------
    def _render_lines(self) -> tuple:
        """(from, to, rgba) segments drawn over the frame."""
        return ()

    def render(self):
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode='rgb_array' or 'human'")
            return None
        if self.render_mode == "human":
            if self._viewer is None:
                self._viewer = HumanViewer(self.model, self.data, self._idx.pelvis_id)
            self._viewer.sync()
            return None
        if self._camera is None:
            self._camera = FollowCamera(self.model, self._idx.pelvis_id, self.width, self.height,
                                        distance=self._camera_distance, elevation=self._camera_elevation)
        self._camera.camera.azimuth = self._camera_azimuth
        return self._camera.render(self.data, self._render_lines())

    def close(self) -> None:
        if self._camera is not None:
            self._camera.close()
            self._camera = None
        if self._viewer is not None:
            self._viewer.close()
            self._viewer = None
