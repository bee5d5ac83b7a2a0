r"""The SIMS finite state machine (Sec. 3.4): run a script's keyframes one skill policy after another.

A :class:`StoryRunner` drives one :class:`~stairenv.environments.sims.SIMSEnv` built on a
room (``SIMSEnv(skill="walk", room=room, ...)``). For each keyframe it switches the env's
goal with ``env.set_task`` (skill, furniture instance, part, hand, caption, style; the
physics is untouched), steps the env with that skill's policy and moves on when the
keyframe has *held* its goal for ``dwell_seconds`` (SIMS, after InterScene: "the next skill
starts when the root has stayed at its target for a set time"):

=========  =====================================================================================
skill      goal and "held" test
=========  =====================================================================================
walk       the root to ``env.approach_point`` of the keyframe's furniture (none: of the next
           interaction's furniture; none either: a random free point of the room); held while
           the root is within ``arrive_radius`` of it (ground distance)
sit, lie   ``info["success"]``: the pelvis within 20 cm (lie: 30 cm) of the seat / bed surface
reach      ``info["success"]``: the hand within 20 cm of a point of the part
getup      ``info["success"]``: the pelvis at standing height in front of the piece (20 cm); a
           getup without furniture gets up from the piece last sat or lain on
=========  =====================================================================================

A keyframe fails on timeout (``max_seconds``), a fall (``info["fell"]``) or diverging physics
(``info["physics_unstable"]``; the env then needs a reset, so the run always stops). After a
failure the run stops (``stop_on_failure=True``; the remaining keyframes are ``"skipped"``) or
goes on with the next keyframe from wherever the character is.

Policies: a mapping skill -> a callable ``obs -> action``, a Stable-Baselines3 model
(``predict(obs, deterministic=True)``) or :data:`KINEMATIC`. Skills SIMS trains without text
(reach, get up: the ``SIMS-Reach-v0`` / ``SIMS-GetUp-v0`` presets) see zeros in the
observation's text slice (``MachineSettings.text_free_skills``).

**No trained skill policy exists yet.** :class:`~stairenv.stories.standin.KinematicStandIn`
(``KINEMATIC``) is a placeholder that is explicitly *not* physics-based: it writes ``qpos``
(and zero velocities) every step to glide the character along free floor, blend it onto a
seat or bed, reach with inverse kinematics or stand it up, and returns a hold-pose action. It
exists to test the state machine's transitions and to make demo videos; its success rates
say nothing about control.

The machine uses the env's public API only (``set_task``, ``step``, ``render``, ``pose``,
``place_on``, ``random_walk_target``, ``approach_point``, ``set_camera``).

Example::

    from stairenv.screenplays import load_database
    from stairenv.stories import KINEMATIC, run_script

    script = load_database().get("tired_bedtime")
    result = run_script(script, {s: KINEMATIC for s in ("walk", "sit", "lie", "reach", "getup")},
                        seed=0, video="story.mp4")
    print(result.success, [k.outcome for k in result.keyframes])
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from stairenv.policy_loading import PRETRAINED, load_policy, policy_label, shipped_policy
from stairenv.stories.standin import KINEMATIC, KinematicStandIn
from stairenv.tasks import sims as task
from stairenv.validation import check_int, check_number

if TYPE_CHECKING:
    from stairenv.environments.sims import SIMSEnv
    from stairenv.screenplays.retrieval import RoomMatch
    from stairenv.world.rooms import Room, RoomConfig

#: What became of a keyframe.
OUTCOMES: tuple[str, ...] = ("success", "timeout", "fell", "unstable", "skipped")
#: Skills that touch furniture (SIMS Table 2 counts these as the script's interactions).
INTERACTIONS: tuple[str, ...] = ("sit", "lie", "reach")
START_POSES: tuple[str, ...] = ("standing", "sitting", "lying")
#: (elevation deg, distance m) of the follow camera when recording in a room.
ROOM_CAMERA: tuple[float, float] = (-65.0, 5.0)

Policy = Callable[[np.ndarray], Any]


class BindingError(ValueError):
    """A keyframe cannot run in the env: unknown furniture instance, a skill the piece does not
    afford, no policy for its skill, or a binding list of the wrong length."""


# --- settings and results --------------------------------------------------------------------
@dataclass(frozen=True)
class MachineSettings:
    """How the state machine decides transitions.

    | field | default | meaning |
    |---|---|---|
    | dwell_seconds | 1.0 | the goal must hold this long (consecutively) before the next keyframe |
    | max_seconds | 20.0 | a keyframe not held by then fails with ``"timeout"`` |
    | arrive_radius | 0.2 | walks: the root within this ground distance (m) of the target holds the goal |
    | stop_on_failure | True | stop at the first failed keyframe (the rest: ``"skipped"``) or go on |
    | text_free_skills | ("reach", "getup") | skills whose policy sees zeros for z (SIMS trains them without text) |
    | part_fallback | True | a part the bound piece lacks (e.g. a script's cabinet "shelf") -> the skill's default part, noted in the result; False: ``BindingError`` |
    | target_speed | None | v* given to ``set_task`` (None: the middle of the env's ``target_speed``) |
    """

    dwell_seconds: float = 1.0
    max_seconds: float = 20.0
    arrive_radius: float = 0.2
    stop_on_failure: bool = True
    text_free_skills: tuple[str, ...] = ("reach", "getup")
    part_fallback: bool = True
    target_speed: float | None = None

    def __post_init__(self) -> None:
        check_number("dwell_seconds", self.dwell_seconds, 0.0, 3600.0)
        check_number("max_seconds", self.max_seconds, 0.0, 36000.0, low_open=True)
        check_number("arrive_radius", self.arrive_radius, 0.0, 10.0, low_open=True)
        if self.dwell_seconds >= self.max_seconds:
            raise ValueError(f"dwell_seconds ({self.dwell_seconds}) must be below max_seconds ({self.max_seconds})")
        object.__setattr__(self, "text_free_skills", tuple(self.text_free_skills))
        for skill in self.text_free_skills:
            if skill not in task.SKILLS:
                raise ValueError(f"text_free_skills must name skills of {list(task.SKILLS)}, got {skill!r}")
        if self.target_speed is not None:
            check_number("target_speed", self.target_speed, 0.0, 10.0)


@dataclass
class KeyframeResult:
    """One keyframe's run. Times in seconds from the keyframe's start; errors in metres."""

    index: int
    skill: str
    category: str | None         # the script's furniture category (None: none)
    furniture: str | None        # the instance used (walk: the piece walked to, if any)
    part: str | None             # the part touched (the goal's label)
    caption: str
    style: str
    outcome: str                 # one of OUTCOMES
    success: bool
    contact_error: float | None  # at the last step (walk: root to target, ground distance)
    min_contact_error: float | None
    seconds: float               # time spent in the keyframe
    steps: int
    held_from: float | None = None  # when the final, completed hold began (success only)
    note: str = ""               # e.g. a part fallback


@dataclass
class StoryResult:
    """A state-machine run: per-keyframe results plus what it ran in."""

    keyframes: list[KeyframeResult]
    room: str | None = None
    script_ids: list[str] = field(default_factory=list)
    video: str | None = None
    frames: int = 0
    policies: dict[str, str] = field(default_factory=dict)
    details: dict[str, Any] = field(default_factory=dict)

    @property
    def success(self) -> bool:
        """Every keyframe succeeded (SIMS Table 2's script success)."""
        return bool(self.keyframes) and all(k.success for k in self.keyframes)

    @property
    def seconds(self) -> float:
        return float(sum(k.seconds for k in self.keyframes))

    @property
    def skills(self) -> list[str]:
        """Skills of the keyframes that ran (not skipped), in order."""
        return [k.skill for k in self.keyframes if k.outcome != "skipped"]

    @property
    def interactions(self) -> list[KeyframeResult]:
        return [k for k in self.keyframes if k.skill in INTERACTIONS]

    @property
    def interactions_succeeded(self) -> int:
        """SIMS Table 2's "success steps": interactions (sit, lie, reach) that succeeded."""
        return sum(k.success for k in self.interactions)

    def to_dict(self) -> dict[str, Any]:
        return {
            "success": self.success,
            "seconds": self.seconds,
            "interactions": len(self.interactions),
            "interactions_succeeded": self.interactions_succeeded,
            "room": self.room,
            "script_ids": list(self.script_ids),
            "video": self.video,
            "frames": self.frames,
            "policies": dict(self.policies),
            "details": self.details,
            "keyframes": [asdict(k) for k in self.keyframes],
        }


# --- policies --------------------------------------------------------------------------------
def describe_policy(policy: Any) -> str:
    """A short human-readable name; the stand-in says that it is not physics-based. The old name of
    ``policy_label(policy, detailed=True)`` (:func:`stairenv.policy_loading.policy_label`)."""
    return policy_label(policy, detailed=True)


def as_policy(policy: Any, env: SIMSEnv) -> Policy:
    """A callable ``obs -> action`` from a callable, an SB3 model (deterministic ``predict``) or
    :data:`KINEMATIC` (a :class:`KinematicStandIn` for ``env``)."""
    if isinstance(policy, str) and policy == KINEMATIC:
        return KinematicStandIn(env)
    if callable(policy):
        return policy
    if callable(getattr(policy, "predict", None)):
        def predict(obs: np.ndarray) -> np.ndarray:
            return policy.predict(obs, deterministic=True)[0]

        predict.__name__ = type(policy).__name__
        return predict
    raise TypeError(f"a policy must be callable (obs -> action), have predict(), or be {KINEMATIC!r}; "
                    f"got {type(policy).__name__}")


def load_skill_policies(specs: Mapping[str, Any] | str, env: Any, seed: int | None = 0) -> dict[str, Any]:
    """Resolve policy specs for every skill: a single spec for all, or skill -> spec.

    Strings go through :func:`stairenv.policy_loading.load_policy` ("zero", "random", an SB3 .zip,
    ``ALGO:path``) with ``env`` giving the spaces; :data:`PRETRAINED` is each skill's shipped policy
    (that of its env, :data:`~stairenv.tasks.sims.SKILL_ENV_IDS`); :data:`KINEMATIC` stays as it is
    (the runner binds a stand-in to its own env); callables and models pass through. Skills not in
    a mapping are left out.
    """
    out: dict[str, Any] = {}
    loaded: dict[str, Any] = {}
    for skill, spec in policy_specs(specs).items():
        if isinstance(spec, (str, os.PathLike)) and os.fspath(spec) == PRETRAINED:
            out[skill] = shipped_policy(task.SKILL_ENV_IDS[skill], env)
        elif isinstance(spec, (str, os.PathLike)) and os.fspath(spec) != KINEMATIC:
            key = os.fspath(spec)
            if key not in loaded:  # one model (or random generator) per distinct spec
                loaded[key] = load_policy(key, env, seed=seed)
            out[skill] = loaded[key]
        else:
            out[skill] = spec
    return out


def policy_specs(specs: Any) -> dict[str, Any]:
    """``specs`` as skill -> policy spec: a mapping is checked, one spec goes to every skill.

    A spec is a string (:data:`KINEMATIC`, "zero", "random", an SB3 .zip, ``ALGO:path``), a
    callable ``obs -> action`` or a model with ``predict()``. Raises TypeError for anything
    else and ValueError for a key that is not a skill.
    """
    if not isinstance(specs, Mapping):
        if not _is_policy_spec(specs):
            raise TypeError(f"policies must be a mapping skill -> policy, or one policy for every skill "
                            f"({_POLICY_KINDS}); got {type(specs).__name__}")
        return dict.fromkeys(task.SKILLS, specs)
    for skill, spec in specs.items():
        if skill not in task.SKILLS:
            raise ValueError(f"policy skills must be among {list(task.SKILLS)}, got {skill!r}")
        if not _is_policy_spec(spec):
            raise TypeError(f"policies[{skill!r}] must be {_POLICY_KINDS}; got {type(spec).__name__}")
    return dict(specs)


_POLICY_KINDS = (f"a callable obs -> action, a model with predict(), or a spec string ({KINEMATIC!r}, 'zero', "
                 f"'random', an SB3 .zip)")


def _is_policy_spec(spec: Any) -> bool:
    return isinstance(spec, (str, os.PathLike)) or callable(spec) or callable(getattr(spec, "predict", None))


# --- the state machine -----------------------------------------------------------------------
class VideoWriter:
    """An MP4 writer (imageio + ffmpeg, libx264 as ``python -m stairenv``) that can print a
    caption on each frame."""

    def __init__(self, path: str | os.PathLike, fps: int, caption: bool = True) -> None:
        import imageio.v2 as imageio

        self.path = Path(path)
        if self.path.suffix.lower() != ".mp4":
            raise ValueError(f"video must be an .mp4 path, got {str(self.path)!r}")
        self.path.parent.mkdir(parents=True, exist_ok=True)
        # libx264 needs even frame sizes; macro_block_size=2 rounds odd ones up without a warning.
        self._writer = imageio.get_writer(self.path, fps=fps, codec="libx264", quality=7, macro_block_size=2,
                                          pixelformat="yuv420p")
        self.caption = caption
        self.frames = 0
        self._font = None

    def append(self, frame: np.ndarray, text: str = "") -> None:
        if self.caption and text:
            frame = self._overlay(frame, text)
        self._writer.append_data(frame)
        self.frames += 1

    def _overlay(self, frame: np.ndarray, text: str) -> np.ndarray:
        from PIL import Image, ImageDraw, ImageFont

        if self._font is None:
            try:
                self._font = ImageFont.load_default(size=max(12, frame.shape[0] // 32))
            except TypeError:  # Pillow < 10.1: one fixed-size bitmap font
                self._font = ImageFont.load_default()
        image = Image.fromarray(frame)
        draw = ImageDraw.Draw(image)
        box = draw.textbbox((8, 6), text, font=self._font)
        draw.rectangle((box[0] - 4, box[1] - 3, box[2] + 4, box[3] + 3), fill=(0, 0, 0))
        draw.text((8, 6), text, fill=(255, 255, 255), font=self._font)
        return np.asarray(image)

    def close(self) -> None:
        self._writer.close()

    def __enter__(self):  # -> Self
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _keyframe_field(kf: Any, name: str, default: Any = None) -> Any:
    return kf.get(name, default) if isinstance(kf, Mapping) else getattr(kf, name, default)


class StoryRunner:
    """Runs keyframes through skill policies in one SIMS env (see the module docstring).

    ``env``: a :class:`~stairenv.environments.sims.SIMSEnv` (gym wrappers are unwrapped; its
    ``render_mode`` must be ``"rgb_array"`` to record video). ``policies``: skill -> policy
    (a callable, an SB3 model or :data:`KINEMATIC`); only the skills a run uses are needed.
    """

    def __init__(self, env: Any, policies: Mapping[str, Any], settings: MachineSettings | None = None) -> None:
        self.env: SIMSEnv = getattr(env, "unwrapped", env)
        if not hasattr(self.env, "set_task"):
            raise TypeError(f"env must be a SIMSEnv, got {type(self.env).__name__}")
        self.settings = settings or MachineSettings()
        unknown = set(policies) - set(task.SKILLS)
        if unknown:
            raise ValueError(f"policies must be keyed by skills of {list(task.SKILLS)}, got {sorted(unknown)}")
        self.policy_names = {skill: describe_policy(p) for skill, p in policies.items()}
        shared: dict[int, Policy] = {}
        self.policies: dict[str, Policy] = {}
        for skill, p in policies.items():
            # one stand-in for all skills that ask for it (it keeps the character's pose between them)
            key = id(KINEMATIC) if isinstance(p, str) and p == KINEMATIC else id(p)
            if key not in shared:
                shared[key] = as_policy(p, self.env)
            self.policies[skill] = shared[key]

    # -- binding
    def bind(self, keyframes: Sequence[Any], binding: Sequence[str | None] | Mapping[int, str | None] | None
             ) -> list[tuple[Any, str | None]]:
        """Pair keyframes with instances: ``binding`` a list (one per keyframe), a mapping
        index -> instance, or None when ``keyframes`` already are (keyframe, instance) pairs."""
        if binding is None:
            pairs = [tuple(item) for item in keyframes]
            if any(len(p) != 2 for p in pairs):
                raise BindingError("without binding, keyframes must be (keyframe, instance) pairs")
            return [(kf, inst) for kf, inst in pairs]
        if isinstance(binding, Mapping):
            return [(kf, binding.get(i)) for i, kf in enumerate(keyframes)]
        binding = list(binding)
        if len(binding) != len(keyframes):
            raise BindingError(f"binding has {len(binding)} entries for {len(keyframes)} keyframes")
        return list(zip(keyframes, binding))

    def _check(self, pairs: Sequence[tuple[Any, str | None]], seat: str | None = None
               ) -> list[tuple[str | None, str]]:
        """Validate every keyframe before running (``seat``: what the character starts on);
        returns (part label or None, note) per keyframe."""
        env = self.env
        parts: list[tuple[str | None, str]] = []
        for i, (kf, inst) in enumerate(pairs):
            skill = _keyframe_field(kf, "skill")
            where = f"keyframe {i} ({skill} {_keyframe_field(kf, 'caption', '')!r})"
            if skill not in task.SKILLS:
                raise BindingError(f"{where}: skill must be one of {list(task.SKILLS)}")
            if skill not in self.policies:
                raise BindingError(f"{where}: no policy for {skill!r}; policies: {sorted(self.policies)}")
            if inst is not None and inst not in env.furniture:
                raise BindingError(f"{where}: no furniture instance {inst!r} in the env; it has {sorted(env.furniture)}")
            if skill in INTERACTIONS and inst is None:
                raise BindingError(f"{where}: {skill} needs a furniture instance, got None")
            if skill == "getup" and inst is None and seat is None:
                raise BindingError(f"{where}: getup without furniture, and nothing was sat or lain on before")
            part, note = None, ""
            if skill in INTERACTIONS or skill == "getup":
                placed = env.furniture[inst if inst is not None else seat]
                wanted = _keyframe_field(kf, "part") if skill != "getup" else None
                try:
                    part = task.resolve_part(placed.family, wanted, skill)
                except ValueError as error:  # the piece does not afford the skill
                    raise BindingError(f"{where}: {error}") from None
                if part not in placed.furniture.labels:
                    if not self.settings.part_fallback:
                        raise BindingError(f"{where}: {placed.family} {placed.name!r} has no part {part!r}; "
                                           f"its parts: {list(placed.furniture.labels)}")
                    fallback = task.resolve_part(placed.family, None, skill)
                    note = f"part {wanted!r} not on {placed.family}; used {fallback!r}"
                    part = fallback
                if wanted is None:
                    part = None  # let the env pick (reach: one of the family's reachable parts)
            if skill in ("sit", "lie"):
                seat = inst
            parts.append((part, note))
        return parts

    # -- running
    def run(self, keyframes: Sequence[Any], binding: Sequence[str | None] | Mapping[int, str | None] | None = None,
            *, seed: int | None = None, reset: bool = True, start_pose: str = "standing", start_on: str | None = None,
            video: str | os.PathLike | Any | None = None, video_every: int = 1) -> StoryResult:
        """Run ``keyframes`` (``Keyframe`` objects or dicts with skill, style, caption, part, hand).

        ``seed``: ``env.reset`` seed (with ``reset``) and the seed of walk targets / reach points.
        ``start_pose``: "sitting" / "lying" seats / lays the character on ``start_on`` (default:
        the first keyframe's instance) first. ``video``: an .mp4 path, or any object with
        ``append(frame, text)`` (e.g. a :class:`VideoWriter`) that receives a frame every
        ``video_every`` steps (the MP4 plays at the env's rate / ``video_every``: offscreen
        rendering costs far more than a step). In a room the camera looks down from above the
        walls (:data:`ROOM_CAMERA`). Raises :class:`BindingError` (before stepping) for keyframes that cannot run.
        """
        if start_pose not in START_POSES:
            raise ValueError(f"start_pose must be one of {list(START_POSES)}, got {start_pose!r}")
        pairs = self.bind(keyframes, binding)
        if start_pose != "standing":
            start_on = start_on if start_on is not None else (pairs[0][1] if pairs else None)
            if start_on not in self.env.furniture:
                raise BindingError(f"start_pose {start_pose!r} needs start_on, a furniture instance of "
                                   f"{sorted(self.env.furniture)}; got {start_on!r}")
        parts = self._check(pairs, start_on if start_pose != "standing" else None)
        env, settings = self.env, self.settings
        if video is not None and env.render_mode != "rgb_array":
            raise ValueError("recording a video needs the env built with render_mode='rgb_array'")
        video_every = int(check_number("video_every", video_every, 1, 10**6))
        if video is not None and env.room is not None:
            # look down on the character from above the walls (the default follow camera, 4.5 m
            # away at -18 deg, sees mostly wall inside a room)
            env.set_camera(*ROOM_CAMERA)

        if reset:
            env.reset(seed=seed)
        rng = np.random.default_rng(seed)
        for policy in {id(p): p for p in self.policies.values()}.values():
            if callable(getattr(policy, "reset", None)):
                policy.reset(seed)
        seat: str | None = None
        if start_pose != "standing":
            env.place_on(env.furniture[start_on], "sit" if start_pose == "sitting" else "lie")
            seat = start_on

        writer, own_writer = video, False
        if isinstance(video, (str, os.PathLike)):
            fps = max(1, round(env.metadata["render_fps"] / video_every))
            writer, own_writer = VideoWriter(video, fps), True
        results: list[KeyframeResult] = []
        stopped = False
        self._steps_run = 0
        try:
            for i, ((kf, inst), (part, note)) in enumerate(zip(pairs, parts)):
                skill = _keyframe_field(kf, "skill")
                caption = _keyframe_field(kf, "caption") or skill
                style = _keyframe_field(kf, "style") or "neutral"
                if stopped:
                    results.append(KeyframeResult(i, skill, _keyframe_field(kf, "furniture"), inst, part, caption, style,
                                                  "skipped", False, None, None, 0.0, 0))
                    continue
                if skill == "getup" and inst is None:
                    inst = seat
                result = self._run_keyframe(i, len(pairs), kf, inst, part, pairs, rng, writer, video_every)
                result.note = note
                results.append(result)
                if skill in ("sit", "lie"):
                    seat = inst
                if not result.success and (settings.stop_on_failure or result.outcome == "unstable"):
                    stopped = True
        finally:
            if own_writer:
                writer.close()
        frames = writer.frames if own_writer else int(getattr(writer, "frames", 0) or 0)
        return StoryResult(results, room=getattr(env.room, "name", None),
                           video=str(writer.path) if own_writer else None, frames=frames,
                           policies=dict(self.policy_names))

    def _walk_target(self, index: int, inst: str | None, pairs: Sequence[tuple[Any, str | None]],
                     rng: np.random.Generator) -> tuple[np.ndarray, str | None]:
        env = self.env
        if inst is None:  # no target of its own: the next interaction's piece, if it comes next
            for kf, nxt in pairs[index + 1:]:
                skill = _keyframe_field(kf, "skill")
                if skill == "walk":
                    break
                if skill in INTERACTIONS and nxt is not None:
                    inst = nxt
                    break
        if inst is not None:
            return env.approach_point(env.furniture[inst]), inst
        here = env.pose()[:2]
        return np.asarray(env.random_walk_target(rng, here), dtype=float), None

    def _run_keyframe(self, i: int, n: int, kf: Any, inst: str | None, part: str | None,
                      pairs: Sequence[tuple[Any, str | None]], rng: np.random.Generator, writer: Any,
                      video_every: int = 1) -> KeyframeResult:
        env, settings = self.env, self.settings
        skill = _keyframe_field(kf, "skill")
        caption = _keyframe_field(kf, "caption") or skill
        style = _keyframe_field(kf, "style") or "neutral"
        category = _keyframe_field(kf, "furniture")
        if skill == "walk":
            target, inst = self._walk_target(i, inst, pairs, rng)
            obs, info = env.set_task("walk", None, caption=caption, style=style, walk_target=target,
                                     target_speed=settings.target_speed, rng=rng)
        else:
            obs, info = env.set_task(skill, inst, part=part, hand=_keyframe_field(kf, "hand"), caption=caption,
                                     style=style, target_speed=settings.target_speed, rng=rng)
        policy = self.policies[skill]
        text = env.observation_structure["text"]
        blind = skill in settings.text_free_skills
        dwell_steps = max(1, math.ceil(settings.dwell_seconds / env.dt - 1e-9))
        max_steps = max(1, math.ceil(settings.max_seconds / env.dt - 1e-9))
        label = f"[{i + 1}/{n}] {skill} ({style}): {caption}"
        error = float(info["contact_error"])
        best = error
        streak, steps, outcome = 0, 0, "timeout"
        while steps < max_steps:
            if blind:
                obs = obs.copy()
                obs[text] = 0.0
            obs, _, _, _, info = env.step(np.asarray(policy(obs)))
            steps += 1
            if info.get("physics_unstable", False):
                outcome = "unstable"
                break
            self._steps_run += 1
            if writer is not None and self._steps_run % video_every == 0:
                writer.append(env.render(), label)
            error = float(info["contact_error"])
            best = min(best, error)
            held = error < settings.arrive_radius if skill == "walk" else bool(info["success"])
            streak = streak + 1 if held else 0
            if info["fell"]:
                outcome = "fell"
                break
            if streak >= dwell_steps:
                outcome = "success"
                break
        success = outcome == "success"
        return KeyframeResult(
            index=i, skill=skill, category=category, furniture=inst, part=env.goal.part, caption=caption,
            style=style, outcome=outcome, success=success, contact_error=error, min_contact_error=best,
            seconds=steps * env.dt, steps=steps, held_from=(steps - streak) * env.dt if success else None,
        )


# --- whole scripts and stories ---------------------------------------------------------------
def story_room(script: Any, rooms: Iterable[tuple[Any, Room]] | None = None, *, config: RoomConfig | None = None,
               seed: int | np.random.Generator | None = 0, timeout: float = 0.05) -> tuple[Room, RoomMatch]:
    """The room for a Script or Story: the best of ``rooms`` ((id, Room) pairs) by graph edit
    distance, or one generated (``generate_room``) with exactly the furniture it needs."""
    from stairenv.screenplays.retrieval import retrieve_room, world_room_builder
    from stairenv.world.rooms import RoomConfig

    candidates = list(rooms or [])
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    match = retrieve_room(script, candidates, fallback=world_room_builder(config or RoomConfig(), rng),
                          timeout=timeout)
    room = match.room if match.generated else dict(candidates)[match.room_id]
    return room, match


def run_script(script: Any, policies: Mapping[str, Any] | str | None = None, *,
               rooms: Iterable[tuple[Any, Room]] | None = None, room_config: RoomConfig | None = None,
               seed: int = 0, settings: MachineSettings | None = None, env_kwargs: Mapping[str, Any] | None = None,
               video: str | os.PathLike | None = None, video_every: int = 1, width: int = 640,
               height: int = 480) -> StoryResult:
    """Run a whole :class:`~stairenv.screenplays.Script` or :class:`~stairenv.screenplays.Story`.

    Finds or builds its room (:func:`story_room`, seeded by ``seed``), binds the keyframes to the
    room's instances (``bind_keyframes``), builds ``SIMSEnv(skill="walk", room=room,
    **env_kwargs)`` and runs a :class:`StoryRunner`. ``policies``: skill -> policy, or one
    spec/policy for all skills (None: :data:`KINEMATIC`, the stand-in); spec strings other
    than ``KINEMATIC`` are loaded with :func:`load_skill_policies`. A script that starts
    sitting or lying starts on its first keyframe's piece. ``video``: an .mp4 path (a frame
    every ``video_every`` steps, ``width`` x ``height``). ``result.details`` records the room
    (``room_summary``), whether it was generated and the substitutions retrieval made.

    Before a room is sought, ``script`` is validated as scripts loaded from files are
    (``ScriptValidationError``; TypeError if it is not a Script or Story) and ``policies`` is
    type-checked (:func:`policy_specs`); a keyframe whose furniture the room lacks raises
    :class:`BindingError`.
    """
    from stairenv.environments.sims import SIMSEnv
    from stairenv.screenplays.retrieval import bind_keyframes

    seed = check_int("seed", seed, 0, 2**63 - 1)  # before any room is drawn with it
    _check_runnable(script)
    specs = policy_specs(policies if policies is not None else KINEMATIC)
    room, match = story_room(script, rooms, config=room_config, seed=seed)
    pairs = bind_keyframes(script.keyframes, match)
    _check_bound(pairs)
    kwargs = dict(env_kwargs or {})
    if video is not None:
        kwargs.update(render_mode="rgb_array", width=width, height=height)
    env = SIMSEnv(skill="walk", room=room, **kwargs)
    try:
        resolved = load_skill_policies(specs, env, seed=seed)
        runner = StoryRunner(env, resolved, settings)
        scripts = getattr(script, "scripts", None) or [script]
        first = scripts[0]
        result = runner.run(pairs, seed=seed, start_pose=getattr(first, "start_pose", "standing"), video=video,
                            video_every=video_every)
    finally:
        env.close()
    result.room = room.name
    result.script_ids = [s.id for s in scripts]
    from stairenv.world.rooms import room_summary

    result.details.update(room_generated=bool(match.generated), room_distance=float(match.distance),
                          room_summary=room_summary(room),
                          substitutions={f"{q[0]}#{q[1]}": list(v) for q, v in match.substitutions.items()})
    return result


def _check_runnable(script: Any) -> None:
    """Validate a Script or Story as scripts loaded from files are (one built in code has
    skipped that): TypeError for another type, ScriptValidationError listing the problems."""
    from stairenv.screenplays.database import Script
    from stairenv.screenplays.schema import ScriptValidationError
    from stairenv.screenplays.story import Story

    if isinstance(script, Script):
        errors, script_id = script.errors(), script.id
    elif isinstance(script, Story):
        errors, script_id = _story_errors(script), None
    else:
        hint = " (build one with Script.from_dict)" if isinstance(script, Mapping) else ""
        raise TypeError(f"script must be a Script or a Story, got {type(script).__name__}{hint}")
    if errors:
        raise ScriptValidationError(errors, script_id if isinstance(script_id, str) else None)


def _story_errors(story: Any) -> list[str]:
    """Problems of a story's scripts (they choose the room) and of the keyframes it runs."""
    from stairenv.screenplays.database import Keyframe, Script
    from stairenv.screenplays.schema import keyframe_sequence_errors

    scripts, keyframes = story.scripts, story.keyframes
    if not isinstance(scripts, (list, tuple)) or not scripts:
        return ["scripts: a story needs a list of at least one Script"]
    if not isinstance(keyframes, (list, tuple)):
        return [f"keyframes: expected a list of Keyframe objects, got {type(keyframes).__name__}"]
    errors = [f"scripts[{k}]: expected a Script, got {type(s).__name__}"
              for k, s in enumerate(scripts) if not isinstance(s, Script)]
    errors += [f"keyframes[{i}]: expected a Keyframe, got {type(kf).__name__}"
               for i, kf in enumerate(keyframes) if not isinstance(kf, Keyframe)]
    if errors:
        return errors
    errors = [f"scripts[{k}].{e}" for k, s in enumerate(scripts) for e in s.errors()]
    first = scripts[0]
    return errors or keyframe_sequence_errors([kf.to_dict() for kf in keyframes], first.start_pose, first.start_at)


def _check_bound(pairs: Sequence[tuple[Any, Any]]) -> None:
    """BindingError naming the first keyframe whose furniture has no item in the room."""
    for i, (kf, inst) in enumerate(pairs):
        if kf.node is not None and inst is None:
            category, instance = kf.node
            raise BindingError(f"keyframe {i} ({kf.skill} {kf.caption!r}): the room has no item for "
                               f"{category} instance {instance}")


__all__ = [
    "INTERACTIONS", "KINEMATIC", "OUTCOMES", "ROOM_CAMERA", "BindingError", "KeyframeResult", "KinematicStandIn",
    "MachineSettings", "StoryResult", "StoryRunner", "VideoWriter", "as_policy",
    "describe_policy", "load_skill_policies", "policy_specs", "run_script", "story_room",
]
