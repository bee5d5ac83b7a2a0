"""MuJoCo Warp physics for the batched env: every world's physics in one Warp model on a GPU (or, for
tests, on Warp's CPU device), behind the same ``BatchPhysics.step`` as the C back-ends.

``gym.make_vec("InterLevel-v0", num_envs=4096, vectorization_mode="vector_entry_point", physics="warp")``
(``train_ppo.py --physics warp``) selects it. Needs the ``gpu`` extra (``mujoco-warp``, ``warp-lang``);
it is imported only when asked for, so a CPU install never loads it.

Design: the per-world ``MjModel`` / ``MjData`` of the batched env stay the source of truth on the host,
and everything the task reads is computed there by the same code as with the C back-end (observation,
reward and termination are one implementation: the CPU kernels of ``stairenv.tasks``). The device holds
one ``mujoco_warp.Model`` with ``nworld`` = the number of worlds and one ``Data``:

- the fields a staircase writes (``StairsSlots.place``: ``body_pos``, ``body_quat``, ``geom_size``,
  ``geom_rbound``, ``geom_aabb``) have a world dimension, so each world keeps its own staircase (the same
  number of step boxes in every world, only their sizes and poses differ), rewritten without recompiling;
- a world marked changed (``world_reset(k)``: the batched env calls it when it resets world k;
  ``world_changed(k)``: a user's write; every world at ``bind``) has those model rows copied from its host
  ``MjModel`` before the next step, and the poses of its geoms (``geom_xpos``, ``geom_xmat``) from its host
  ``MjData``: MuJoCo Warp's kinematics computes the poses of geoms on moving bodies only, so a tread (a
  static body) would otherwise keep the pose ``put_data`` gave it, and the character would walk through
  the staircase it stands on;
- each ``step``: the stepped worlds' state (``qpos``, ``qvel``, ``act``, ``qacc_warmstart``, ``time``)
  and ``ctrl`` up, one copy per field (the host state is the truth: a reset, a push an evaluation
  writes into ``qvel``, a test's forced divergence all reach the device without being announced);
  ``nstep`` substeps of ``mujoco_warp.step`` on the device (one CUDA graph on a GPU); then ``qpos``,
  ``qvel``, ``act`` and ``qacc_warmstart`` down (one copy per field, not per world) into each stepped
  world's ``MjData``, its ``time`` advanced there by ``nstep`` timesteps in float64 as ``mj_step`` does.
  The env then runs ``mj_kinematics`` on the host (``_physics_sound``, as after ``mj_step``), so the body
  poses the task reads come from these ``qpos``.

Opt-in, ``state_on_device=True`` (``WarpPhysics`` docstring): the device's state is the truth between resets.
Only worlds marked changed (``world_reset``, ``world_changed``: a reset, or an announced write) are read
from their ``MjData``, the state goes up only after such a change, the ctrl comes as one array, the device
runs the kinematics, and the stepped worlds' state stays in ``state`` as arrays that the env finishes from;
the worlds' ``MjData`` are written only by ``sync_worlds`` (so a write into one follows its sync).

Options (integrator, solver, iterations, line-search iterations, tolerances, timestep, cone) are the
``MjModel``'s: ``mujoco_warp.put_model`` reads them, and ``settings()`` reports both sides. MuJoCo Warp
computes in float32 and is not bit-deterministic, so a world stepped here follows the C back-end's
trajectory only within a tolerance (``tests/test_warp_physics.py``, ``docs/gpu.md``).

Divergence: MuJoCo C resets a world whose state blows up and counts a warning, which the env's
divergence check reads; MuJoCo Warp does neither. Here a world whose state comes back non-finite or
beyond MuJoCo's own bound (1e10) gets the same warning count (``mjWARN_BADQACC``), and one whose contacts
or constraints overflowed the device's buffers (``nconmax``, ``njmax``: contacts would be dropped) gets
``mjWARN_CONTACTFULL`` counted in ``overflows``; the env truncates a diverged world alone, as with the C
back-end (``info["physics_unstable"]``), while its speed check catches the rest.

Which ids: InterLevel-v0 and its ablations (InterLevel2D-v0, InterSceneStairs-v0), PlaMo-v0 and
PlaMoNaivePaths-v0: one model structure for every world, only values per world. A PlaMo world's terrain
is held in tile slots (``stairenv.world.tiles.TerrainSlots``: boxes for stairs, a height field per slope or
rough tile, written at a reset and whenever the character comes near a new tile, ``_focus_terrain``). The
boxes are per-world poses and sizes, as the treads are. MuJoCo Warp shares ``hfield_data`` and
``hfield_size`` among worlds, so the device model holds every world's height fields as assets of their own
(world k's field h is asset k * nhfield + h: ``hfield_adr``, ``hfield_nrow``, ``hfield_ncol``, ``hfield_size``
and ``hfield_data`` made ``nworld`` times as long) and routes each world's height-field geoms to its own
through the per-world ``geom_dataid``, the routing MuJoCo Warp's maintainers point to; a world whose
terrain was written (``world_changed``: the batched env announces every world whose ``_model_written`` a
focus set) has its fields and height fields copied up before the next step. Not supported, refused with a
``ValueError``:

- PlaMoScene-v0: a scene's landmarks and obstacles are bodies built per scene and the model is recompiled
  when the scene changes (``add_scene_to_spec``), so worlds differ in their bodies and geoms.
- SIMS (the five SIMS-* skills): each reset builds a room of furniture bodies and recompiles the model,
  so the worlds differ in their number of bodies and geoms, which one Warp model cannot hold. It would
  take a fixed set of furniture slots (parked bodies with convex parts resized per world, as
  ``StairsSlots`` does for treads) so that every world has the same structure.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import mujoco
import numpy as np

# a world as ``batch_physics.World`` (not imported from there: ``make_physics`` imports this module)
World = tuple[mujoco.MjModel, mujoco.MjData]

#: model fields that a world's staircase (``StairsSlots.place``) or terrain tiles (``TerrainSlots``, whose
#: geoms also move within their slot's body) write: given a world dimension on the device
PER_WORLD_MODEL_FIELDS = ("body_pos", "body_quat", "geom_pos", "geom_quat", "geom_size", "geom_rbound", "geom_aabb")
#: height-field data a world's terrain tiles may hold at most on the device (float32 values, all worlds):
#: 2^28 (1 GiB); ``TerrainSlots`` needs 4 x 41 x 41 a world (27 KB), 27.5M at 4,096 worlds
MAX_HFIELD_VALUES = 2 ** 28
#: geom poses copied up from a changed world's host data: the device never computes them for static
#: bodies' geoms (the treads); for moving bodies' geoms its kinematics overwrites them at the next substep
GEOM_POSE_FIELDS = ("geom_xpos", "geom_xmat")
#: state copied up before and down after every step (``ctrl`` and ``time`` go up too)
STATE_FIELDS = ("qpos", "qvel", "act", "qacc_warmstart")
#: MuJoCo's bound on a state value (``mjMAXVAL``): beyond it (or non-finite) C resets the world
MAX_VALUE = 1e10
_BADQACC = int(mujoco.mjtWarning.mjWARN_BADQACC)
_CONTACTFULL = int(mujoco.mjtWarning.mjWARN_CONTACTFULL)

#: why each unsupported env class is refused (see the module docstring)
UNSUPPORTED = {
    "PlaMoSceneEnv": "PlaMo scenes build their landmarks and obstacles as bodies and recompile the model when "
                     "the scene changes, so worlds differ in their bodies and geoms, which one MuJoCo Warp "
                     "model cannot hold",
    "SIMSEnv": "SIMS builds each world's furniture as bodies and recompiles the model at every reset, so "
               "worlds differ in their bodies and geoms, which one MuJoCo Warp model cannot hold",
}


def check_supported(env_class: type) -> None:
    """``ValueError`` naming ``physics`` unless ``env_class`` can run on the Warp back-end (InterLevel, PlaMo's
    path following)."""
    from stairenv.environments.interlevel import InterLevelEnv
    from stairenv.environments.plamo import PlaMoEnv
    from stairenv.environments.plamo_scene import PlaMoSceneEnv
    if issubclass(env_class, InterLevelEnv) or (issubclass(env_class, PlaMoEnv)
                                                and not issubclass(env_class, PlaMoSceneEnv)):
        return
    reason = next((UNSUPPORTED[c.__name__] for c in env_class.__mro__ if c.__name__ in UNSUPPORTED),
                  "only worlds of one structure (InterLevel's staircases, PlaMo's terrain tiles) are supported")
    raise ValueError(f"physics='warp' does not support {env_class.__name__}: {reason}. Supported: "
                     "InterLevel-v0, InterLevel2D-v0, InterSceneStairs-v0, PlaMo-v0, PlaMoNaivePaths-v0; use "
                     "physics='mujoco' for this env")


def _import_warp():
    try:
        import mujoco_warp
        import warp
    except ImportError as error:    # the gpu extra is not installed
        raise ImportError("physics='warp' needs MuJoCo Warp: pip install 'stairenv[gpu]' "
                          f"(mujoco-warp, warp-lang); {error}") from error
    return warp, mujoco_warp


class WarpPhysics:
    """All worlds of a batched env on one MuJoCo Warp model (see the module docstring).

    ``device``: a Warp device ("cuda:0", "cpu"; default Warp's preferred one: the first GPU, else the
    CPU); ``nconmax`` / ``njmax``: contacts (a pool of ``nconmax x nworld`` shared by all worlds) and
    constraint rows per world on the device (the C back-end saw at most 8 contacts and 32 rows in 3,000
    steps of random actions on InterLevel; overflows are counted in ``overflows``); ``graph``: replay the
    ``nstep`` substeps as one captured graph (default: on a GPU, where it saves a launch per kernel; Warp
    replays graphs on its CPU device too, which the tests use to check the capture). ``bind(worlds)`` must
    be called once with every world of the batch before ``step`` (the batched env does).

    ``state_on_device`` (opt-in; default False, the host's ``MjData`` is the truth): the device's state is
    the truth between resets. A step then takes the worlds' ctrl as one array (``step(..., ctrl=...)``),
    reads only the ``MjData`` of worlds marked changed (``world_reset(k)``: a reset; ``world_changed(k)``: a
    write into a world's ``MjData`` that must reach the device, after ``sync_worlds``) and sends the state up
    only when one was (whole fields), runs the kinematics on the device and leaves the stepped worlds' state in ``state`` as arrays (``qpos``,
    ``qvel``, ``xpos``, ``xmat``, ``diverged``) instead of writing each world's ``MjData``; ``sync_worlds(ks)``
    writes worlds' ``MjData`` on request (rendering, reading a world's data)."""

    def __init__(self, device: str | None = None, nconmax: int = 32, njmax: int = 128,
                 graph: bool | None = None, state_on_device: bool = False) -> None:
        self._wp, self._mjw = _import_warp()
        wp = self._wp
        wp.config.quiet = True
        wp.config.log_level = 30    # warnings only: no line per compiled or loaded kernel module
        wp.init()
        self.device = wp.get_device(device) if device is not None else wp.get_preferred_device()
        self.nconmax, self.njmax = int(nconmax), int(njmax)
        self.graph = self.device.is_cuda if graph is None else bool(graph)
        #: why a CUDA graph could not be captured (the substeps then launch kernel by kernel), if so
        self.graph_error: str | None = None
        self.state_on_device = bool(state_on_device)
        #: with ``state_on_device``: the last step's stepped worlds (rows in ``step``'s order) as arrays
        self.state: dict[str, np.ndarray] | None = None
        self.model = self.data = None
        self.worlds: list[World] = []
        self._slot: dict[int, int] = {}
        self._bound: Sequence[World] | None = None
        self._graphs: dict[int, object] = {}
        self._fields = False    # whether the worlds hold height fields (routed per world at ``bind``)
        #: world-steps whose device buffers overflowed (contacts or constraint rows dropped; a full contact
        #: pool flags every world of that step), since construction
        self.overflows = 0

    # --- binding ----------------------------------------------------------------------------------
    def bind(self, worlds: Sequence[World]) -> None:
        """Build the device model and data for these worlds (one structure: the first world's model,
        the staircase fields per world), every world marked changed."""
        wp, mjw = self._wp, self._mjw
        if not worlds:
            raise ValueError("WarpPhysics.bind needs at least one world")
        model0, data0 = worlds[0]
        for k, (model, _) in enumerate(worlds):
            if (model.nq, model.nv, model.nu, model.na, model.nbody, model.ngeom) != (
                    model0.nq, model0.nv, model0.nu, model0.na, model0.nbody, model0.ngeom):
                raise ValueError(f"physics='warp' needs one model structure in every world; world {k} differs")
        n = len(worlds)
        self.worlds = list(worlds)
        self._bound, self._every_slot = worlds, np.arange(n)    # a step of the list bound: every world, in order
        self._slot = {id(data): k for k, (_, data) in enumerate(worlds)}
        with wp.ScopedDevice(self.device):
            self.model = mjw.put_model(model0, batch_sizes=dict.fromkeys(PER_WORLD_MODEL_FIELDS, n))
            self.model.opt.warn_overflow = 0    # counted per world instead of printed
            self.data = mjw.put_data(model0, data0, nworld=n, nconmax=self.nconmax, njmax=self.njmax)
            self._route_height_fields(worlds)
        self._timestep = float(model0.opt.timestep)
        self._model_host = {name: np.stack([getattr(m, name) for m, _ in worlds]).astype(np.float32)
                            for name in PER_WORLD_MODEL_FIELDS}
        self._geom_pose_host = {name: np.stack([getattr(d, name) for _, d in worlds]).astype(np.float32)
                                for name in GEOM_POSE_FIELDS}
        # each world's fields as views, looked up once (the buffers of an MjModel and an MjData never move): a
        # changed world's rows are copied from them, not from a field looked up again per world and reset
        self._model_views = {name: [getattr(m, name) for m, _ in worlds] for name in PER_WORLD_MODEL_FIELDS}
        self._geom_pose_views = {name: [getattr(d, name) for _, d in worlds] for name in GEOM_POSE_FIELDS}
        self._state_views = {name: [getattr(d, name) for _, d in worlds] for name in STATE_FIELDS}
        self._ctrl_views = [d.ctrl for _, d in worlds]
        self._state_host = {name: np.zeros((n, getattr(data0, name).size), dtype=np.float32)
                            for name in STATE_FIELDS}
        self._ctrl_host = np.zeros((n, model0.nu), dtype=np.float32)
        self._time_host = np.zeros(n, dtype=np.float64)
        self._changed = np.ones(n, dtype=bool)
        self._state_changed = np.ones(n, dtype=bool)    # state_on_device: rows to send up
        self._stale = np.zeros(n, dtype=bool)    # state_on_device: worlds whose MjData lags the device
        self._graphs = {}

    def _route_height_fields(self, worlds: Sequence[World]) -> None:
        """Every world's height fields as assets of their own on the device (world k's field h: asset
        k * nhfield + h), each world's height-field geoms routed to its own through ``geom_dataid``."""
        wp = self._wp
        model0 = worlds[0][0]
        n, nfield, size = len(worlds), model0.nhfield, model0.nhfielddata
        self._fields = nfield > 0
        if not nfield:
            return
        if n * size > MAX_HFIELD_VALUES:
            raise ValueError(f"physics='warp': {n} worlds x {size} height-field values each exceed the "
                             f"{MAX_HFIELD_VALUES} the device holds (a render mode's terrain view is one large "
                             "height field: build the batched env without render_mode)")
        for k, (model, _) in enumerate(worlds):
            if model.nhfielddata != size or not np.array_equal(model.hfield_nrow, model0.hfield_nrow):
                raise ValueError(f"physics='warp' needs one model structure in every world; world {k}'s height "
                                 "fields differ")
        device = self.model
        device.hfield_adr = wp.array((np.arange(n)[:, None] * size + model0.hfield_adr).ravel().astype(np.int32),
                                     dtype=int)
        device.hfield_nrow = wp.array(np.tile(model0.hfield_nrow, n).astype(np.int32), dtype=int)
        device.hfield_ncol = wp.array(np.tile(model0.hfield_ncol, n).astype(np.int32), dtype=int)
        self._field_size_views = [m.hfield_size for m, _ in worlds]
        self._field_data_views = [m.hfield_data for m, _ in worlds]
        device.hfield_size = wp.array(np.concatenate(self._field_size_views).astype(np.float32), dtype=wp.vec4)
        device.hfield_data = wp.array(np.concatenate(self._field_data_views).astype(np.float32), dtype=float)
        dataid = np.tile(model0.geom_dataid.astype(np.int32), (n, 1))
        fields = model0.geom_type == int(mujoco.mjtGeom.mjGEOM_HFIELD)
        dataid[:, fields] += (np.arange(n, dtype=np.int32) * nfield)[:, None]
        device.geom_dataid = wp.array(dataid, dtype=int)
        device.nhfield, device.nhfielddata = n * nfield, n * size

    def _upload_height_fields(self, ks: list[int]) -> None:
        """The height fields of changed worlds ``ks``: one copy of the whole arrays when many changed, else a
        copy of each world's rows."""
        device, size, nfield = self.model, self.worlds[0][0].nhfielddata, self.worlds[0][0].nhfield
        if 4 * len(ks) > len(self.worlds):
            self._assign(device.hfield_size, np.concatenate(self._field_size_views))
            self._assign(device.hfield_data, np.concatenate(self._field_data_views))
            return
        for k in ks:
            device.hfield_size[k * nfield:(k + 1) * nfield].assign(
                self._field_size_views[k].astype(np.float32))
            device.hfield_data[k * size:(k + 1) * size].assign(self._field_data_views[k].astype(np.float32))

    def world_reset(self, k: int | Sequence[int]) -> None:
        """World ``k`` (or worlds ``k``) was reset on the host, its ``MjData`` and staircase written whole (the
        batched env calls it): copy the per-world model fields up before the next step (its state goes up
        at every step anyway; with ``state_on_device``, its state goes up then too, and its ``MjData`` no
        longer lags)."""
        self._changed[k] = True
        self._state_changed[k] = True
        self._stale[k] = False

    def world_changed(self, k: int | Sequence[int]) -> None:
        """A write into world ``k``'s (or worlds ``k``') host ``MjData`` or staircase that must reach the device,
        sent up before the next step as a reset's is. With ``state_on_device`` a world whose ``MjData`` lags
        the device (stepped since ``sync_worlds``) is refused with a ``RuntimeError``: the write would have
        gone into an old state, which would be sent up and rewind the world. Sync it, write, then announce."""
        if self.state_on_device:
            ks = np.atleast_1d(np.asarray(k, dtype=np.int64))
            lagging = ks[self._stale[ks]].tolist()
            if lagging:
                raise RuntimeError(
                    f"world(s) {lagging}: the MjData lags the device's state (state_on_device=True), so a write "
                    f"into it went into an old state, which would rewind the world: call "
                    f"physics.sync_worlds({lagging}) before writing into it, then world_changed")
        for j in np.atleast_1d(np.asarray(k, dtype=np.int64)).tolist():    # the static geoms' poses after a
            mujoco.mj_kinematics(*self.worlds[j])                            # model write (a focus's tiles)
        self.world_reset(k)

    def sync_worlds(self, ks: Sequence[int] | None = None) -> None:
        """With ``state_on_device``: write worlds ``ks`` (default: every world whose ``MjData`` lags) from the
        device's last state into their ``MjData`` (``qpos``, ``qvel``, ``act``, warm start, time, then
        ``mj_kinematics``). Without it every step writes them, and this does nothing."""
        if not self.state_on_device:
            return
        ks = np.flatnonzero(self._stale) if ks is None else np.asarray(ks, dtype=np.int64)
        for k in ks.tolist():
            if not self._stale[k]:
                continue
            model, data = self.worlds[k]
            for name, host in self._state_host.items():
                if host.shape[1]:
                    self._state_views[name][k][:] = host[k]
            data.time = self._time_host[k]
            mujoco.mj_kinematics(model, data)
            self._stale[k] = False

    def settings(self) -> dict[str, tuple]:
        """The options the device runs with next to the host model's: ``{name: (host, device)}``."""
        host = self.worlds[0][0].opt
        dev = self.model.opt

        def first(value):
            return value.numpy().reshape(-1)[0].item() if hasattr(value, "numpy") else value
        return {name: (getattr(host, name) if not hasattr(getattr(host, name), "item") else getattr(host, name).item(),
                       first(getattr(dev, name)))
                for name in ("timestep", "integrator", "solver", "iterations", "ls_iterations", "tolerance",
                             "ls_tolerance", "cone", "disableflags", "enableflags")}

    # --- stepping ---------------------------------------------------------------------------------
    def step(self, worlds: Sequence[World], nstep: int, then: Callable[[int], None] | None = None,
             meanwhile: Callable[[], None] | None = None,
             collect: Callable[[list[int]], None] | None = None, ctrl: np.ndarray | None = None) -> None:
        if self.state_on_device and worlds:
            self._step_on_device(worlds, nstep, then, meanwhile, collect, ctrl)
            return
        if not worlds:
            if meanwhile is not None:
                meanwhile()
            return
        if self.model is None:
            raise RuntimeError("WarpPhysics.bind(worlds) must be called before step")
        wp = self._wp
        slots = self._slots(worlds)
        self._upload(worlds, slots)
        with wp.ScopedDevice(self.device):
            self.data.overflow.zero_()
            self._launch(nstep)
            if meanwhile is not None:    # the host resets other worlds while the device steps
                meanwhile()
            down = {name: getattr(self.data, name).numpy() for name in STATE_FIELDS}
            overflow = self.data.overflow.numpy()
        self._download(worlds, slots, nstep, down, overflow)
        if then is not None:
            for k in range(len(worlds)):
                then(k)
        if collect is not None:
            collect(list(range(len(worlds))))

    def _step_on_device(self, worlds, nstep, then, meanwhile, collect, ctrl) -> None:
        """``step`` with ``state_on_device`` (see the class docstring)."""
        if self.model is None:
            raise RuntimeError("WarpPhysics.bind(worlds) must be called before step")
        if ctrl is None:
            raise ValueError("WarpPhysics(state_on_device=True).step needs the worlds' ctrl as one array (ctrl=)")
        wp, mjw = self._wp, self._mjw
        slots = self._slots(worlds)
        self._upload_model_rows()
        changed = np.flatnonzero(self._state_changed).tolist()
        # reset (or announced) worlds: their MjData into the host rows (one gathered copy per field), then up;
        # otherwise the device holds these fields already (the host rows are its last download)
        if changed:
            for name, host in self._state_host.items():
                if host.shape[1]:
                    views = self._state_views[name]
                    host[changed] = np.array([views[k] for k in changed])
                    self._assign(getattr(self.data, name), host)
            self._time_host[changed] = [self.worlds[k][1].time for k in changed]
            self._state_changed[:] = False
        self._assign(self.data.time, self._time_host)    # every step: the host keeps the time in float64
        self._ctrl_host[slots] = ctrl
        self._assign(self.data.ctrl, self._ctrl_host)
        with wp.ScopedDevice(self.device):
            self.data.overflow.zero_()
            self._launch(nstep)
            mjw.kinematics(self.model, self.data)    # body poses at the new qpos, as the host's mj_kinematics
            if meanwhile is not None:
                meanwhile()
            down = {name: getattr(self.data, name).numpy() for name in (*STATE_FIELDS, "xpos", "xmat")}
            overflow = self.data.overflow.numpy()
        n = len(self.worlds)
        for name in STATE_FIELDS:
            self._state_host[name][:] = down[name].reshape(n, -1)
        times = self._time_host[slots]
        for _ in range(nstep):    # as mj_step advances it, in float64
            times += self._timestep
        self._time_host[slots] = times
        self._stale[slots] = True
        every = slots is self._every_slot    # then each field's rows are the whole array, converted once
        rows = {name: (down[name].reshape(n, -1) if every else down[name].reshape(n, -1)[slots]).astype(np.float64)
                for name in (*STATE_FIELDS, "xpos", "xmat")}
        bad = _diverged(rows["qpos"], rows["qvel"], rows["qacc_warmstart"])
        self.overflows += int(self._overflowed(overflow[slots]).sum())
        self.state = {"qpos": rows["qpos"], "qvel": rows["qvel"], "xpos": rows["xpos"].reshape(len(slots), -1, 3),
                      "xmat": rows["xmat"].reshape(len(slots), -1, 9), "diverged": bad}
        if then is not None:
            for k in range(len(worlds)):
                then(k)
        if collect is not None:
            collect(list(range(len(worlds))))

    def _slots(self, worlds: Sequence[World]) -> np.ndarray:
        """The device rows of ``worlds`` (those of the list ``bind`` got, without a lookup per world)."""
        if worlds is self._bound:
            return self._every_slot
        try:
            return np.fromiter((self._slot[id(data)] for _, data in worlds), dtype=np.int64, count=len(worlds))
        except KeyError:
            raise ValueError("WarpPhysics.step got a world it was not bound to (bind all worlds first)") from None

    def _overflowed(self, overflow: np.ndarray) -> np.ndarray:
        """Which worlds' contacts or constraint rows overflowed the device's buffers."""
        mjw = self._mjw
        return (overflow & int(mjw.OverflowType.NEFC | mjw.OverflowType.NJMAX_NNZ | mjw.OverflowType.BROADPHASE
                               | mjw.OverflowType.NARROWPHASE)) != 0

    def _upload_model_rows(self) -> None:
        """A changed world's staircase or terrain: its rows of the per-world model fields, its height fields
        and its static geoms' poses."""
        changed = np.flatnonzero(self._changed)
        if changed.size:
            ks = changed.tolist()
            if self._fields:
                self._upload_height_fields(ks)
            for name, host in self._model_host.items():    # each field's changed rows gathered in one copy
                views = self._model_views[name]
                host[changed] = np.array([views[k] for k in ks])
                self._assign(getattr(self.model, name), host)
            for name, host in self._geom_pose_host.items():    # the treads' poses (see GEOM_POSE_FIELDS)
                views = self._geom_pose_views[name]
                host[changed] = np.array([views[k] for k in ks])
                self._assign(getattr(self.data, name), host)
            self._changed[:] = False

    def _upload(self, worlds: Sequence[World], slots: np.ndarray) -> None:
        self._upload_model_rows()
        datas = [data for _, data in worlds]
        order = slots.tolist()
        for name, host in self._state_host.items():    # the host's state is the truth (resets, pushes)
            if host.shape[1]:
                views = self._state_views[name]
                host[slots] = np.array([views[k] for k in order])
                self._assign(getattr(self.data, name), host)
        self._time_host[slots] = np.fromiter((data.time for data in datas), dtype=np.float64, count=len(datas))
        self._assign(self.data.time, self._time_host)
        views = self._ctrl_views
        self._ctrl_host[slots] = np.array([views[k] for k in order])
        self._assign(self.data.ctrl, self._ctrl_host)

    @staticmethod
    def _assign(array, host: np.ndarray) -> None:
        """One host-to-device copy of a whole field (``host`` reshaped to the device array's layout)."""
        if array.size == 0:
            return
        shape = tuple(array.shape) + tuple(getattr(array.dtype, "_shape_", ()))
        array.assign(np.ascontiguousarray(host, dtype=np.float32).reshape(shape))

    def _launch(self, nstep: int) -> None:
        wp, mjw = self._wp, self._mjw
        if not self.graph:
            for _ in range(nstep):
                mjw.step(self.model, self.data)
            return
        graph = self._graphs.get(nstep)
        if graph is None:
            if not self._graphs.get("loaded"):    # kernels compiled and loaded before a capture
                for _ in range(nstep):
                    mjw.step(self.model, self.data)
                self._graphs["loaded"] = True
                return
            try:
                with wp.ScopedCapture() as capture:
                    for _ in range(nstep):
                        mjw.step(self.model, self.data)
            except Exception as error:    # noqa: BLE001  (a driver without graph support: launch kernel by kernel)
                self.graph, self.graph_error = False, f"{type(error).__name__}: {error}"
                for _ in range(nstep):
                    mjw.step(self.model, self.data)
                return
            graph = self._graphs[nstep] = capture.graph
        wp.capture_launch(graph)

    def _download(self, worlds: Sequence[World], slots: np.ndarray, nstep: int, down: dict[str, np.ndarray],
                  overflow: np.ndarray) -> None:
        rows = {name: value.reshape(len(self.worlds), -1)[slots].astype(np.float64) for name, value in down.items()}
        qpos, qvel, act, warm = (rows[name] for name in STATE_FIELDS)
        bad = _diverged(qpos, qvel, warm)
        full = self._overflowed(overflow[slots])
        self.overflows += int(full.sum())
        times = np.fromiter((data.time for _, data in worlds), dtype=np.float64, count=len(worlds))
        for _ in range(nstep):    # as mj_step advances it, in float64
            times += self._timestep
        views = self._state_views
        has_act = act.shape[1] > 0
        for k, ((_, data), slot) in enumerate(zip(worlds, slots.tolist())):
            views["qpos"][slot][:] = qpos[k]
            views["qvel"][slot][:] = qvel[k]
            views["qacc_warmstart"][slot][:] = warm[k]
            if has_act:
                views["act"][slot][:] = act[k]
            data.time = times[k]
        for k in np.flatnonzero(bad).tolist():
            worlds[k][1].warning[_BADQACC].number += 1
        for k in np.flatnonzero(full).tolist():
            worlds[k][1].warning[_CONTACTFULL].number += 1

    def close(self) -> None:
        self._graphs = {}
        self.model = self.data = None
        self.worlds = []
        self._slot = {}
        self._bound = None


def _diverged(qpos: np.ndarray, qvel: np.ndarray, warm: np.ndarray) -> np.ndarray:
    """Worlds (rows) whose state is non-finite or beyond MuJoCo's bound: those C would reset (see the module
    docstring, "Divergence"; the warm start is the last acceleration, which C's ``mj_checkAcc`` bounds)."""
    return ~(np.isfinite(qpos).all(1) & np.isfinite(qvel).all(1) & np.isfinite(warm).all(1)
             & (np.abs(qpos) <= MAX_VALUE).all(1) & (np.abs(qvel) <= MAX_VALUE).all(1)
             & (np.abs(warm) <= MAX_VALUE).all(1))
