"""The AMP style reward as a vectorised-env wrapper, so any PPO library trains unchanged.

Every env of the package puts its last K frames of style features in
``info["amp_obs"]``. The wrappers read them after each vectorised step, score
them with the discriminator, replace the reward by

    r = w_task * r_task + w_style * r_style

(keeping both parts in ``info["task_reward"]`` and ``info["style_reward"]``),
store the agent's windows in a replay buffer and, every ``update_interval``
transitions, train the discriminator for ``updates_per_round`` minibatches of
reference windows against replayed agent windows.

With reference windows that carry conditions (``ReferenceWindows(conditions=...)``, e.g.
text embeddings of each clip's description as in SIMS), the discriminator judges
``[amp_obs, amp_condition]``: the env's ``info["amp_condition"]`` (a SIMS env's caption
embedding) is appended to its window, so style can be conditioned on text.

- ``AMPVecEnvWrapper``: Stable-Baselines3 ``VecEnv`` (``DummyVecEnv``, ``SubprocVecEnv``,
  the batched ``stairenv.vec_sb3.make_sb3_vec_env``).
- ``AMPVectorWrapper``: ``gymnasium.vector.VectorEnv`` (next-step autoreset; ``SyncVectorEnv``,
  the batched ``gym.make_vec(id, n, vectorization_mode="vector_entry_point")``).

Without a ``style`` both build the envs' own (:func:`default_style`): their reference clips
(:func:`default_reference`: the env's ``reference_motion``, else its class's
``DEFAULT_REFERENCE_MOTION``) in windows of their ``amp_history`` frames at ``1 / dt``, the
default discriminator, training in the background::

    venv = AMPVecEnvWrapper(make_sb3_vec_env("InterLevel-v0", n_envs=64))

Each step's N windows are scored in one call (one batch through the discriminator's back-end).

``background_training=True`` runs each training round in a worker thread while
the envs step (torch releases the GIL in its kernels; on a machine with a spare
core the round costs the step loop almost nothing). Scoring then uses a snapshot
of the weights taken when the round started, so the rewards lag the synchronous
schedule by exactly one round (``update_interval`` transitions), deterministically:
the minibatches are drawn in the calling thread and a round is joined before the
next starts. ``scoring="bf16"`` scores in bfloat16 (see ``AMPDiscriminator``).

``save(path)`` / ``load(path)`` keep the discriminator, its optimiser and input
normaliser, the weights and the schedule; the replay buffer's contents are not
saved (its size is), it refills within one round. The file holds only tensors and
plain values, and ``load`` reads it with ``torch.load(weights_only=True)``: a file
that asks to build any other Python object is refused (``AMPStateError``), so
opening one runs no code from it.
"""

from __future__ import annotations

import pickle
import re
import warnings
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path

import gymnasium as gym
import numpy as np
import torch
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper

from stairenv.motion.rsi import load_reference_library
from stairenv.style.discriminator import (
    SCORERS,
    AMPDiscriminator,
    DiscriminatorConfig,
    ReplayBuffer,
    plain_config,
)
from stairenv.style.reference import ReferenceWindows
from stairenv.validation import check_choice, check_number


class AMPStateError(ValueError):
    """An AMP state file that cannot be read, or holds more than tensors and plain values."""


#: torch's advice on a refused file (load it with ``weights_only=False``) is never passed on: the
#: sentences of its messages that mention these are dropped
_ADVICE = ("weights_only", "trusted source", "arbitrary code", "add_safe_globals", "safe_globals",
           "documentation of torch.load", "pytorch.org")


def _unpickler_complaint(err: Exception) -> str:
    """torch's reason for not reading a file (truncated, foreign), without any advice to load unsafely."""
    if isinstance(err, pickle.UnpicklingError):  # torch's whole message is about loading it unsafely
        return "its pickle holds instructions that a safe load refuses"
    sentences = re.split(r"(?<=[.!?])\s+|\n+", str(err))
    kept = [part for part in sentences if part.strip() and not any(a in part for a in _ADVICE)]
    return " ".join(" ".join(kept).split()) or type(err).__name__


#: the largest pickle read for the names of its globals
_MAX_PICKLE_BYTES = 64 * 2**20


def _pickle_globals(path: Path) -> list[str]:
    """The globals (``module.name``) the pickles of a torch file name: ``data.pkl`` in a zip file, else
    the file's own pickles one after another (torch's legacy format, or a plain pickle). Read with
    ``pickletools`` (opcodes only: nothing is built or run); [] where there is nothing to read."""
    import zipfile

    try:
        if zipfile.is_zipfile(path):
            with zipfile.ZipFile(path) as archive:
                member = next((m for m in archive.infolist() if m.filename.endswith("data.pkl")), None)
                if member is None or member.file_size > _MAX_PICKLE_BYTES:
                    return []
                data = archive.read(member)
        elif path.stat().st_size <= _MAX_PICKLE_BYTES:
            data = path.read_bytes()
        else:
            return []
    except (OSError, ValueError, EOFError, RuntimeError, zipfile.BadZipFile):
        return []
    return _opcode_globals(data)


def _opcode_globals(data: bytes) -> list[str]:
    """The globals the pickles in ``data`` name, in order (``pickletools``: opcodes only, nothing built)."""
    import io
    import pickletools

    names: list[str] = []
    strings: list[str] = []
    stream = io.BytesIO(data)
    try:
        while stream.tell() < len(data):  # legacy torch files: several pickles, then raw storage bytes
            for opcode, arg, _ in pickletools.genops(stream):
                if opcode.name in ("GLOBAL", "INST"):
                    names.append(str(arg).replace(" ", "."))
                elif opcode.name == "STACK_GLOBAL" and len(strings) >= 2:
                    names.append(f"{strings[-2]}.{strings[-1]}")
                if isinstance(arg, str):
                    strings.append(arg)
    except Exception:  # noqa: BLE001  (the storage bytes, or a truncated pickle: the names so far)
        pass
    return names


#: the global a refusal names: "Unsupported global: GLOBAL m.f was not an allowed global" (2.1-2.12),
#: "Trying to load unsupported GLOBAL m.f whose module m is blocked" (2.13)
_REFUSED_GLOBAL = re.compile(r"\bGLOBAL ([A-Za-z_][\w.]*)")
#: globals a torch file legitimately names (torch's own rebuild functions and types)
_TORCH_GLOBALS = ("torch.", "collections.OrderedDict", "builtins.set", "builtins.frozenset", "builtins.bytearray",
                  "_codecs.encode")


def load_weights_only(path: Path):
    """``torch.load(path, weights_only=True)`` on the CPU: tensors and plain values, nothing run."""
    with warnings.catch_warnings():  # a crafted file's pickle protocol: torch asks to report it to them
        warnings.filterwarnings("ignore", message="Detected pickle protocol", category=UserWarning)
        return torch.load(path, weights_only=True, map_location="cpu")


def refused_object(err: Exception, path: Path) -> str | None:
    """The Python object (``module.name``) that ``torch.load(path, weights_only=True)`` refused to build,
    None when ``err`` is no such refusal (a truncated or foreign file).

    The exception's type and the file decide, not torch's wording (which changed between versions, and
    comes with advice to load the file unsafely): torch raises every refusal of its weights-only
    unpickler as ``pickle.UnpicklingError``, whatever the reason; the object is the one torch's message
    names, else the first non-torch global in the file's pickles (torch 2.13 refuses a plain pickle at
    its first unsupported opcode, before reaching any global). A pickle naming no such global cannot
    build anything to run (text, or a pickle torch cannot read): None."""
    if not isinstance(err, pickle.UnpicklingError):
        return None
    named = _REFUSED_GLOBAL.search(str(err))
    if named:
        return named[1]
    foreign = [name for name in _pickle_globals(path) if not name.startswith(_TORCH_GLOBALS)]
    return foreign[0] if foreign else None


#: the plain values of a saved AMP state: name -> (type, least value, whether a state must have it)
_STATE_FIELDS = {
    "w_task": (float, None, True), "w_style": (float, None, True), "update_interval": (int, 1, True),
    "updates_per_round": (int, 1, True), "rounds": (int, 0, True), "replay_size": (int, 1, False),
    "reference_num_frames": (int, 1, False), "reference_fps": (float, 0.0, False),
    "reference_condition_dim": (int, 0, False), "background_training": (bool, None, False),
}


def _check_state(path: Path, state: dict) -> None:
    """``AMPStateError`` naming the file and the entry for a plain value of the wrong type or range."""
    for name, (kind, least, required) in _STATE_FIELDS.items():
        if name not in state:
            if required:
                raise AMPStateError(f"{path}: not an AMP state (no {name!r} entry; written by AMPStyleReward.save?)")
            continue
        value = state[name]
        if kind is bool:
            ok = isinstance(value, bool)
        elif kind is int:
            ok = isinstance(value, int) and not isinstance(value, bool)
        else:
            ok = isinstance(value, (int, float)) and not isinstance(value, bool) and np.isfinite(value)
        if not ok or (least is not None and value < least):
            wanted = {bool: "a bool", int: "an integer", float: "a finite number"}[kind]
            raise AMPStateError(f"{path}: entry {name!r} is {value!r:.60}; it must be {wanted}"
                                + ("" if least is None else f" >= {least}"))
    scoring = state.get("scoring")
    if scoring is not None and not isinstance(scoring, str):
        raise AMPStateError(f"{path}: entry 'scoring' is {scoring!r:.60}; it must be a string or None")
    disc = state["discriminator"]
    if not isinstance(disc, dict) or not all(k in disc for k in ("input_dim", "config", "model", "optimizer")):
        raise AMPStateError(f"{path}: entry 'discriminator' is not a saved discriminator (input_dim, config, "
                            "model, optimizer)")
    dim = disc["input_dim"]
    if not isinstance(dim, int) or isinstance(dim, bool) or dim < 1:
        raise AMPStateError(f"{path}: entry 'discriminator' has input_dim {dim!r:.60}; it must be a positive integer")


def read_amp_state(path: str | Path) -> dict:
    """The dict ``AMPStyleReward.save`` wrote, read without running code from the file."""
    path = Path(path)
    if not path.is_file():
        raise AMPStateError(f"no AMP state file {str(path)!r}")
    try:
        state = load_weights_only(path)
    except Exception as err:  # noqa: BLE001  (truncated or foreign files surface as many types)
        refused = refused_object(err, path)
        if refused is not None:
            raise AMPStateError(
                f"{path}: refused: it asks to build the Python object {refused}, and AMP states hold only "
                "tensors and plain values (such a file could run code when opened; nothing from it was run); "
                "it was not written by AMPStyleReward.save, or has been altered"
            ) from None
        raise AMPStateError(f"{path}: cannot read as an AMP state: truncated, or another kind of file? "
                            f"({type(err).__name__}: {_unpickler_complaint(err)})") from None
    if not isinstance(state, dict) or "discriminator" not in state:
        raise AMPStateError(f"{path}: not an AMP state (no 'discriminator' entry; written by AMPStyleReward.save?)")
    _check_state(path, state)
    return state


class AMPStyleReward:
    """Discriminator, replay buffer and training schedule shared by both wrappers.

    ``device``: where a discriminator built here lives and trains (the replay buffer and the windows
    stay numpy on the host; each minibatch and each step's windows are copied to the device)."""

    def __init__(
        self,
        reference: ReferenceWindows,
        w_task: float = 0.5,
        w_style: float = 0.5,
        config: DiscriminatorConfig | None = None,
        update_interval: int = 2048,
        updates_per_round: int = 2,
        train: bool = True,
        seed: int = 0,
        discriminator: AMPDiscriminator | None = None,
        background_training: bool = False,
        scoring: str | None = None,
        device: str | torch.device = "cpu",
    ) -> None:
        self.reference = reference
        self.w_task = check_number("w_task", w_task, 0.0)
        self.w_style = check_number("w_style", w_style, 0.0)
        self.update_interval = int(check_number("update_interval", update_interval, 1))
        self.updates_per_round = int(check_number("updates_per_round", updates_per_round, 0))
        self.train = bool(train)
        torch.manual_seed(seed)
        self.rng = np.random.default_rng(seed)
        if discriminator is None:
            discriminator = AMPDiscriminator(reference.dim, config or DiscriminatorConfig(), scoring=scoring or "auto",
                                             device=device)
        elif scoring is not None:
            discriminator.scoring = check_choice("scoring", scoring, SCORERS)
        self.disc = discriminator
        self.disc.noise_generator.manual_seed(seed)
        if self.disc.input_dim != reference.dim:
            raise ValueError(f"discriminator input {self.disc.input_dim} != reference window size {reference.dim}")
        self.config = self.disc.config
        self.replay = ReplayBuffer(self.config.replay_size, reference.dim)
        self.pending = 0
        self.rounds = 0
        self.last_stats: dict[str, float] = {}
        self.background_training = bool(background_training)
        self._worker: ThreadPoolExecutor | None = None
        self._job: Future | None = None

    def __call__(self, amp_obs: np.ndarray, task_reward: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Combined reward and style reward of a batch of transitions (all of them scored in one
        call); also learns from them."""
        if amp_obs.shape[1] != self.reference.dim:
            raise ValueError(
                f"info['amp_obs'] has {amp_obs.shape[1] - self.reference.condition_dim} numbers per env but the "
                f"reference windows have {self.reference.feature_dim}: make the env's amp_history equal the "
                f"reference's num_frames"
            )
        if self._job is not None:  # a round trains in the background: leave its core to it
            self.disc.scoring_threads = 1 if self.training_in_background() else None
        style = self.disc.reward(amp_obs)
        if self.train:
            self.replay.add(amp_obs)
            self.pending += len(amp_obs)
            if self.pending >= self.update_interval:
                self.pending = 0
                if self.background_training:
                    self._start_background_round()
                else:
                    self.train_round()
        return self.w_task * np.asarray(task_reward, dtype=np.float64) + self.w_style * style, style

    def agent_inputs(self, windows: list | np.ndarray, conditions: list | np.ndarray | None,
                     out: np.ndarray | None = None) -> np.ndarray:
        """The discriminator's inputs for a batch of env windows: the windows, followed by the
        envs' conditions when the reference windows are conditioned."""
        need = self.reference.condition_dim
        if need == 0:
            if out is not None and np.shape(windows[0])[-1] == out.shape[1]:
                return np.stack(windows, out=out)  # straight into float32, as the discriminator reads them
            return np.stack(windows)
        if conditions is None:
            raise KeyError("the reference windows are conditioned but the envs put no 'amp_condition' in info "
                           "(SIMS envs do; pass conditions=None to ReferenceWindows for other envs)")
        conditions = np.asarray(conditions, dtype=np.float32).reshape(len(windows), -1)
        if conditions.shape[1] != need:
            raise ValueError(f"info['amp_condition'] has {conditions.shape[1]} numbers per env, "
                             f"the reference conditions have {need}")
        return np.concatenate((np.stack(windows).astype(np.float32), conditions), axis=1)

    def _minibatches(self, updates: int | None) -> list[tuple[np.ndarray, np.ndarray]]:
        updates = self.updates_per_round if updates is None else updates
        if len(self.replay) == 0:
            return []
        batch = self.config.batch_size
        return [(self.reference.sample(batch, self.rng), self.replay.sample(batch, self.rng)) for _ in range(updates)]

    def _train_on(self, minibatches: list[tuple[np.ndarray, np.ndarray]]) -> list[dict[str, float]]:
        return [self.disc.update(reference, agent) for reference, agent in minibatches]

    def _record(self, stats: list[dict[str, float]]) -> None:
        if stats:
            self.rounds += 1
            self.last_stats = {k: float(np.mean([s[k] for s in stats])) for k in stats[0]}

    def train_round(self, updates: int | None = None) -> dict[str, float]:
        """Train the discriminator now (after any background round in flight); returns its statistics."""
        self.wait()
        self.disc.unfreeze_scoring()  # scoring follows this round at once
        self._record(self._train_on(self._minibatches(updates)))
        return self.last_stats

    def _start_background_round(self) -> None:
        self.wait()  # the previous round, whose weights the snapshot below then holds
        minibatches = self._minibatches(None)
        if not minibatches:
            return
        self.disc.freeze_scoring()
        if self._worker is None:
            self._worker = ThreadPoolExecutor(max_workers=1, thread_name_prefix="amp-discriminator")
        self._job = self._worker.submit(self._train_on, minibatches)

    def training_in_background(self) -> bool:
        """Whether a background training round is running now."""
        return self._job is not None and not self._job.done()

    def wait(self) -> None:
        """Finish a background training round in flight (its errors are raised here). Scoring keeps
        the snapshot it uses until the next round starts, so waiting changes no reward."""
        job, self._job = self._job, None
        self.disc.scoring_threads = None
        if job is not None:
            self._record(job.result())

    def close(self) -> None:
        """Finish any background round and stop the worker thread."""
        self.wait()
        if self._worker is not None:
            self._worker.shutdown()
            self._worker = None

    def save(self, path: str | Path) -> Path:
        """Write the state as tensors and plain values only (``load`` refuses anything else)."""
        self.wait()
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        torch.save({
            "discriminator": self.disc.state(),
            "w_task": float(self.w_task), "w_style": float(self.w_style),
            "update_interval": int(self.update_interval), "updates_per_round": int(self.updates_per_round),
            "replay_size": int(self.config.replay_size), "rounds": int(self.rounds),
            "reference_num_frames": int(self.reference.num_frames), "reference_fps": float(self.reference.fps),
            "reference_condition_dim": int(self.reference.condition_dim),
            "background_training": bool(self.background_training), "scoring": str(self.disc.scoring),
            "config": plain_config(self.config),
        }, path)
        return path

    @classmethod
    def load(cls, path: str | Path, reference: ReferenceWindows, train: bool = True, seed: int = 0) -> "AMPStyleReward":
        """The state ``save`` wrote; raises ``AMPStateError`` for a file it cannot read or that holds
        more than tensors and plain values (nothing in the file is run)."""
        state = read_amp_state(path)
        saved = int(state.get("reference_condition_dim", 0))
        if saved != reference.condition_dim:
            raise ValueError(f"{path} was trained with {saved}-number conditions, the reference windows "
                             f"carry {reference.condition_dim}: build them with the same conditions")
        saved_dim = int(state["discriminator"]["input_dim"])
        if saved_dim != reference.dim:
            raise ValueError(f"{path} judges windows of {saved_dim} numbers ({state.get('reference_num_frames')} "
                             f"frames), the reference windows have {reference.dim} ({reference.num_frames} frames): "
                             "build them with the saved number of frames")
        disc = AMPDiscriminator.from_state(state["discriminator"])
        style = cls(reference, state["w_task"], state["w_style"], update_interval=state["update_interval"],
                    updates_per_round=state["updates_per_round"], train=train, seed=seed, discriminator=disc,
                    background_training=state.get("background_training", False), scoring=state.get("scoring"))
        style.rounds = state["rounds"]
        return style


#: What the wrappers read from the first env to build its default style (``default_reference``).
_DEFAULT_STYLE_ATTRIBUTES = ("amp_history", "dt", "reference_motion", "DEFAULT_REFERENCE_MOTION")


def _first_env_attribute(venv, name: str):
    """Attribute ``name`` of the first env of an SB3 ``VecEnv`` or a ``gymnasium.vector.VectorEnv``
    (through vector wrappers, which do not forward ``get_attr``); AttributeError if it has none."""
    if isinstance(venv, VecEnv):
        if not venv.has_attr(name):
            raise AttributeError(name)
        return venv.get_attr(name, indices=[0])[0]
    while not hasattr(venv, "get_attr") and isinstance(getattr(venv, "env", None), gym.vector.VectorEnv):
        venv = venv.env
    if not hasattr(venv, "get_attr"):
        raise AttributeError(name)
    return venv.get_attr(name)[0]


def default_reference(venv) -> ReferenceWindows:
    """The reference windows the wrappers build when given no ``style``: the envs' own reference
    clips, ``load_reference_library(env.reference_motion)`` (the env's ``reference_motion`` keyword,
    else its class's ``DEFAULT_REFERENCE_MOTION``: InterLevel's synthesised stairs set, SIMS'
    interactions), cut into windows of ``env.amp_history`` frames at the env's control rate
    (``fps = 1 / env.dt``), unconditioned.

    ``venv``: an SB3 ``VecEnv`` (``DummyVecEnv``, ``SubprocVecEnv``, ``stairenv.vec_sb3.SB3BatchedVecEnv``,
    wrapped or not) or a ``gymnasium.vector.VectorEnv`` (``SyncVectorEnv``, the batched
    ``HumanoidVectorEnv``) of stairenv envs; the first env's attributes are read. ``TypeError`` for
    envs without AMP features (no ``amp_history``: not a stairenv env). A text-conditioned
    discriminator (SIMS) needs its conditions: build ``ReferenceWindows(..., conditions=...)`` and
    ``AMPStyleReward`` yourself."""
    values = {}
    for name in _DEFAULT_STYLE_ATTRIBUTES:
        try:
            values[name] = _first_env_attribute(venv, name)
        except AttributeError:
            raise TypeError(
                f"the envs of {type(venv).__name__} have no AMP features ({name!r} missing; stairenv envs put "
                "their style windows in info['amp_obs'] and have amp_history, dt and a reference motion): "
                "pass style=AMPStyleReward(ReferenceWindows(...)) built for these envs"
            ) from None
    source = values["reference_motion"]
    library = load_reference_library(values["DEFAULT_REFERENCE_MOTION"] if source is None else source)
    return ReferenceWindows(library, num_frames=int(values["amp_history"]), fps=1.0 / float(values["dt"]))


def default_style(venv, **kwargs) -> AMPStyleReward:
    """``AMPStyleReward(default_reference(venv), **kwargs)``: the envs' own reference windows and
    the default discriminator (the paper's [1024, 512], reward 0.5 task + 0.5 style, a training
    round of 2 minibatches every 2048 transitions) trained in the background
    (``background_training=True`` unless ``kwargs`` says otherwise: the rounds leave the step loop
    where a core is spare, the rewards lag one round; where none is, as under the batched env's
    physics pool on two cores, a round costs the same either way)."""
    kwargs.setdefault("background_training", True)
    return AMPStyleReward(default_reference(venv), **kwargs)


class AMPVecEnvWrapper(VecEnvWrapper):
    """Stable-Baselines3 VecEnv wrapper adding the AMP style reward.

    ``style``: the discriminator and its schedule; None (the default) builds the envs' own,
    :func:`default_style` (their reference clips in windows of their ``amp_history`` frames at
    ``1 / dt``, the default discriminator, background training); ``TypeError`` if the envs have no
    AMP features. Each step's N windows are scored in one call."""

    def __init__(self, venv: VecEnv, style: AMPStyleReward | None = None) -> None:
        super().__init__(venv)
        style = default_style(venv) if style is None else style
        self.style = style
        self._amp = np.empty((self.num_envs, style.reference.dim), dtype=np.float32)

    def reset(self):
        return self.venv.reset()

    def close(self) -> None:
        self.style.close()
        super().close()

    def step_wait(self):
        obs, task_reward, dones, infos = self.venv.step_wait()
        conditions = ([info.get("amp_condition") for info in infos] if self.style.reference.condition_dim
                      else None)
        if conditions is not None and any(c is None for c in conditions):
            conditions = None  # agent_inputs explains
        amp = self.style.agent_inputs([info["amp_obs"] for info in infos], conditions, out=self._amp)
        reward, style = self.style(amp, task_reward)
        for info, task, sty in zip(infos, task_reward.tolist(), style.tolist()):
            info["task_reward"] = task
            info["style_reward"] = sty
        return obs, reward.astype(np.float32), dones, infos


class AMPVectorWrapper(gym.vector.VectorWrapper):
    """``gymnasium.vector`` wrapper adding the AMP style reward (next-step autoreset envs).

    With next-step autoreset, the step after an episode ends only resets that env
    (reward 0): those entries get no style reward and are not learned from.
    ``style`` as for :class:`AMPVecEnvWrapper` (None: :func:`default_style` of ``env``, e.g. a
    ``SyncVectorEnv`` or the batched ``gym.make_vec(id, n, vectorization_mode="vector_entry_point")``).
    """

    def __init__(self, env: gym.vector.VectorEnv, style: AMPStyleReward | None = None) -> None:
        super().__init__(env)
        style = default_style(env) if style is None else style
        self.style = style
        self._resetting = np.zeros(self.num_envs, dtype=bool)

    def reset(self, **kwargs):
        self._resetting[:] = False
        return self.env.reset(**kwargs)

    def close(self, **kwargs) -> None:
        self.style.close()
        super().close(**kwargs)

    def step(self, actions):
        obs, task_reward, terminated, truncated, info = self.env.step(actions)
        if "amp_obs" not in info:
            raise KeyError("the wrapped envs put no 'amp_obs' in info; AMP needs stairenv envs (or compatible)")
        live = ~self._resetting
        task_reward = np.asarray(task_reward, dtype=np.float64)
        reward = task_reward.copy()
        style = np.zeros(self.num_envs)
        if live.any():
            conditions = info.get("amp_condition")
            amp = self.style.agent_inputs(np.asarray(info["amp_obs"])[live],
                                          None if conditions is None else np.asarray(conditions)[live])
            reward[live], style[live] = self.style(amp, task_reward[live])
        info = dict(info)
        info["task_reward"] = task_reward
        info["style_reward"] = style
        self._resetting = np.logical_or(terminated, truncated)
        return obs, reward, terminated, truncated, info
