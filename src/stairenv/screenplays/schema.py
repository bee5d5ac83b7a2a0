"""JSON schema, validator and semantic rules for SIMS short scripts.

A short script (SIMS Sec. 3.2 and the supplement's Tables 6-9, with our field names) is::

    {
      "id": "tired_bedtime",                 # [a-z0-9_-], unique in a database
      "title": "Bedtime at last",
      "summary": "An exhausted person drags ... and lies down on the bed.",
      "scene": "bedroom",                    # optional: bedroom | living room | dining room | study
      "start_pose": "standing",              # optional, default standing; sitting | lying: the
                                             #   script continues a seated / lying character and
                                             #   its first keyframe is the getup
      "keyframes": [
        {"skill": "walk", "style": "tired", "caption": "shuffles slowly ...", "furniture": "bed"},
        {"skill": "lie",  "style": "tired", "caption": "lies on the back ...", "furniture": "bed",
         "part": "bed_surface"},
        ...
      ]
    }

Keyframe fields: ``skill`` (walk | sit | lie | reach | getup), ``style`` (one of the eight
SIMS styles or neutral), ``caption`` (free text for the text embedding z), ``furniture``
(a category; required for sit, lie and reach; for walk the target, omitted for wandering;
for getup the seat, omitted = where the character is), ``part`` (optional labelled part),
``hand`` (optional left | right, reach only) and ``instance`` (optional integer >= 0, default 0:
which item of that category, e.g. ``"the second wardrobe"``; SIMS' (category, instance)
node ids in the merged layout graph).

Two layers of checks:

* :func:`schema_errors` checks :data:`SCRIPT_SCHEMA` (a JSON Schema draft 2020-12 subset)
  with the small validator below (``jsonschema`` is not a dependency). Every error names the
  bad field path, e.g. ``keyframes[2].skill: 'fly' is not one of ['walk', ...]``.
* :func:`semantic_errors` runs the keyframes through the FSM's pose state machine
  (SIMS Sec. 3.4). Rules enforced:

  1. walk needs a standing character (a seated or lying one gets up first);
  2. sit, lie and reach need a standing character *at* that furniture: the last walk
     (since the character last stood up) went to the same category and instance
     (a character that just got up from an item is at that item);
  3. getup follows a sit or lie (immediately: nothing else can run while seated or lying;
     so no reach from a seat and no lie straight after a sit), and its furniture, when
     given, is the one sat or lain on;
  4. affordances: sit on chair, armchair, stool, sofa, bed, double bed; lie on sofa, bed,
     double bed; reach and walk to anything;
  5. ``part`` is allowed for the skill (sit, lie: seat or bed_surface; reach: any
     part) and exists on the furniture (:data:`FURNITURE_PARTS`); walk and getup take none;
  6. ``hand`` only on reach;
  7. ``start_pose`` sitting/lying needs a first keyframe getup with a furniture that affords it (one
     sits on what rule 4 lets sit, lies on what it lets lie).

  A script may end seated or lying (stories insert a getup between scripts, see
  :mod:`stairenv.screenplays.story`).
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

SKILLS: tuple[str, ...] = ("walk", "sit", "lie", "reach", "getup")
INTERACTIONS: tuple[str, ...] = ("sit", "lie", "reach")
STYLES: tuple[str, ...] = ("happy", "angry", "hurried", "tired", "sad", "stressed", "drunk", "relaxed")
STYLES_WITH_NEUTRAL: tuple[str, ...] = (*STYLES, "neutral")
FURNITURE: tuple[str, ...] = (
    "chair", "armchair", "stool", "sofa", "bed", "double bed",
    "table", "cabinet", "wardrobe", "bookshelf", "lamp",
)
PARTS: tuple[str, ...] = (
    "seat", "backrest", "armrest", "bed_surface", "table_top", "shelf", "handle", "switch",
)
SCENES: tuple[str, ...] = ("bedroom", "living room", "dining room", "study")
POSES: tuple[str, ...] = ("standing", "sitting", "lying")
HANDS: tuple[str, ...] = ("left", "right")

#: Which furniture affords which contact skill (walk: any target).
AFFORDANCES: dict[str, frozenset[str]] = {
    "sit": frozenset({"chair", "armchair", "stool", "sofa", "bed", "double bed"}),
    "lie": frozenset({"sofa", "bed", "double bed"}),
    "reach": frozenset(FURNITURE),
    "walk": frozenset(FURNITURE),
    "getup": frozenset({"chair", "armchair", "stool", "sofa", "bed", "double bed"}),
}
#: Labelled parts each furniture category has.
FURNITURE_PARTS: dict[str, frozenset[str]] = {
    "chair": frozenset({"seat", "backrest"}),
    "armchair": frozenset({"seat", "backrest", "armrest"}),
    "stool": frozenset({"seat"}),
    "sofa": frozenset({"seat", "backrest", "armrest"}),
    "bed": frozenset({"bed_surface"}),
    "double bed": frozenset({"bed_surface"}),
    "table": frozenset({"table_top"}),
    "cabinet": frozenset({"table_top", "shelf", "handle"}),
    "wardrobe": frozenset({"shelf", "handle"}),
    "bookshelf": frozenset({"shelf"}),
    "lamp": frozenset({"switch"}),
}
#: Parts a skill may target.
SKILL_PARTS: dict[str, frozenset[str]] = {
    "sit": frozenset({"seat", "bed_surface"}),
    "lie": frozenset({"bed_surface", "seat"}),
    "reach": frozenset(PARTS),
    "walk": frozenset(),
    "getup": frozenset(),
}

_ID_PATTERN = r"^[a-z0-9][a-z0-9_\-]*$"

KEYFRAME_SCHEMA: dict[str, Any] = {
    "type": "object",
    "required": ["skill", "style", "caption"],
    "additionalProperties": False,
    "properties": {
        "skill": {"enum": list(SKILLS)},
        "style": {"enum": list(STYLES_WITH_NEUTRAL)},
        "caption": {"type": "string", "minLength": 3, "maxLength": 200},
        "furniture": {"enum": list(FURNITURE)},
        "part": {"enum": list(PARTS)},
        "hand": {"enum": list(HANDS)},
        "instance": {"type": "integer", "minimum": 0, "maximum": 9},
    },
    "allOf": [
        {
            "if": {"properties": {"skill": {"enum": list(INTERACTIONS)}}, "required": ["skill"]},
            "then": {"required": ["furniture"]},
        }
    ],
}

SCRIPT_SCHEMA: dict[str, Any] = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "title": "SIMS short script",
    "type": "object",
    "required": ["id", "title", "summary", "keyframes"],
    "additionalProperties": False,
    "properties": {
        "id": {"type": "string", "pattern": _ID_PATTERN, "maxLength": 64},
        "title": {"type": "string", "minLength": 1, "maxLength": 80},
        "summary": {"type": "string", "minLength": 10, "maxLength": 400},
        "scene": {"enum": list(SCENES)},
        "start_pose": {"enum": list(POSES)},
        "keyframes": {"type": "array", "minItems": 1, "maxItems": 20, "items": KEYFRAME_SCHEMA},
    },
}

# --------------------------------------------------------------------------- validator

_SUPPORTED = {
    "$schema", "title", "description", "type", "enum", "const", "required", "properties",
    "additionalProperties", "items", "minItems", "maxItems", "minLength", "maxLength",
    "pattern", "minimum", "maximum", "allOf", "if", "then", "else",
}
_TYPES: dict[str, tuple[type, ...]] = {
    "object": (dict,),
    "array": (list, tuple),
    "string": (str,),
    "integer": (int,),
    "number": (int, float),
    "boolean": (bool,),
    "null": (type(None),),
}


#: Problems a :class:`ScriptValidationError` message lists; the rest are counted (``errors`` has all).
MAX_REPORTED_ERRORS = 20


def _elide(text: str, limit: int = 80) -> str:
    """``text`` cut in the middle to at most ``limit`` characters (both ends stay readable)."""
    if len(text) <= limit:
        return text
    keep = (limit - 5) // 2
    return f"{text[:keep]} ... {text[-keep:]}"


def _show(value: Any) -> str:
    """A bounded repr for messages: a script's values can be arbitrarily long."""
    return _elide(repr(value))


class ScriptValidationError(ValueError):
    """A script failed validation; ``errors`` lists one message per problem, each starting
    with the bad field's path (``keyframes[2].skill: ...``). The message shows the first
    :data:`MAX_REPORTED_ERRORS` and counts the rest."""

    def __init__(self, errors: Sequence[str], script_id: str | None = None):
        self.errors = list(errors)
        self.script_id = None if script_id is None else _elide(str(script_id), 160)
        where = f"script {self.script_id!r}" if script_id else "script"
        shown = self.errors[:MAX_REPORTED_ERRORS]
        if len(self.errors) > len(shown):
            shown.append(f"... and {len(self.errors) - len(shown)} more problem(s)")
        super().__init__(f"{where} is invalid:\n  " + "\n  ".join(shown))


def _check_supported(schema: Mapping[str, Any], path: str = "#") -> None:
    unknown = set(schema) - _SUPPORTED
    if unknown:
        raise ValueError(f"schema keyword(s) {sorted(unknown)} at {path} are not supported by this validator")
    for key in ("items", "if", "then", "else", "additionalProperties"):
        if isinstance(schema.get(key), Mapping):
            _check_supported(schema[key], f"{path}/{key}")
    for name, sub in schema.get("properties", {}).items():
        _check_supported(sub, f"{path}/properties/{name}")
    for i, sub in enumerate(schema.get("allOf", [])):
        _check_supported(sub, f"{path}/allOf/{i}")


def _join(path: str, key: str | int) -> str:
    if isinstance(key, int):
        return f"{path}[{key}]"
    return f"{path}.{key}" if path else key


def _is_type(value: Any, name: str) -> bool:
    if name in ("integer", "number") and isinstance(value, bool):
        return False
    return isinstance(value, _TYPES[name])


def validate_instance(value: Any, schema: Mapping[str, Any], path: str = "") -> list[str]:
    """Errors of ``value`` against ``schema`` (the subset of JSON Schema in ``_SUPPORTED``).

    Each error is ``"<path>: <message>"``; the root is written ``(root)``.
    """
    errors: list[str] = []
    where = path or "(root)"
    if "type" in schema:
        types = schema["type"] if isinstance(schema["type"], list) else [schema["type"]]
        if not any(_is_type(value, t) for t in types):
            errors.append(f"{where}: {_show(value)} is not of type {' or '.join(repr(t) for t in types)}")
            return errors
    if "enum" in schema and value not in schema["enum"]:
        errors.append(f"{where}: {_show(value)} is not one of {list(schema['enum'])}")
    if "const" in schema and value != schema["const"]:
        errors.append(f"{where}: {_show(value)} is not {schema['const']!r}")
    if isinstance(value, str):
        if "minLength" in schema and len(value) < schema["minLength"]:
            errors.append(f"{where}: {_show(value)} is shorter than {schema['minLength']} characters")
        if "maxLength" in schema and len(value) > schema["maxLength"]:
            errors.append(f"{where}: text is longer than {schema['maxLength']} characters")
        if "pattern" in schema and not re.search(schema["pattern"], value):
            errors.append(f"{where}: {_show(value)} does not match {schema['pattern']!r}")
    if _is_type(value, "number"):
        if "minimum" in schema and value < schema["minimum"]:
            errors.append(f"{where}: {_show(value)} is less than the minimum {schema['minimum']}")
        if "maximum" in schema and value > schema["maximum"]:
            errors.append(f"{where}: {_show(value)} is greater than the maximum {schema['maximum']}")
    if isinstance(value, dict):
        for name in schema.get("required", []):
            if name not in value:
                errors.append(f"{_join(path, name)}: required field is missing")
        props = schema.get("properties", {})
        for name, sub in props.items():
            if name in value:
                errors.extend(validate_instance(value[name], sub, _join(path, name)))
        extra = schema.get("additionalProperties", True)
        for name in value:
            if name in props:
                continue
            if extra is False:
                shown = _elide(name) if isinstance(name, str) else name
                errors.append(f"{_join(path, shown)}: unknown field (allowed: {sorted(props)})")
            elif isinstance(extra, Mapping):
                errors.extend(validate_instance(value[name], extra, _join(path, name)))
    if isinstance(value, (list, tuple)):
        if "minItems" in schema and len(value) < schema["minItems"]:
            errors.append(f"{where}: has {len(value)} item(s), fewer than {schema['minItems']}")
        if "maxItems" in schema and len(value) > schema["maxItems"]:
            errors.append(f"{where}: has {len(value)} items, more than {schema['maxItems']}")
        if isinstance(schema.get("items"), Mapping):
            for i, item in enumerate(value):
                errors.extend(validate_instance(item, schema["items"], _join(path, i)))
    for sub in schema.get("allOf", []):
        errors.extend(validate_instance(value, sub, path))
    if "if" in schema:
        branch = "then" if not validate_instance(value, schema["if"], path) else "else"
        if branch in schema:
            errors.extend(validate_instance(value, schema[branch], path))
    return errors


_check_supported(SCRIPT_SCHEMA)


def schema_errors(script: Any) -> list[str]:
    """Errors of ``script`` against :data:`SCRIPT_SCHEMA` (empty when it conforms)."""
    return validate_instance(script, SCRIPT_SCHEMA)


# --------------------------------------------------------------------------- semantics


def _kf_get(kf: Any, name: str, default: Any = None) -> Any:
    if isinstance(kf, Mapping):
        return kf.get(name, default)
    value = getattr(kf, name, default)
    return default if value is None and name == "instance" else value


def _label(cat: str | None, inst: int) -> str:
    if cat is None:
        return "no furniture"
    return f"the {cat}" if inst == 0 else f"the {cat} #{inst}"


def pose_after(keyframes: Iterable[Any], start_pose: str = "standing",
               start_at: tuple[str, int] | None = None) -> tuple[str, tuple[str, int] | None]:
    """(pose, (category, instance) the character is at) after ``keyframes``, assuming they are
    valid (see :func:`semantic_errors`)."""
    pose, at = start_pose, start_at
    for kf in keyframes:
        skill = _kf_get(kf, "skill")
        cat = _kf_get(kf, "furniture")
        inst = int(_kf_get(kf, "instance", 0) or 0)
        if skill == "walk":
            pose, at = "standing", ((cat, inst) if cat else None)
        elif skill in ("sit", "lie"):
            pose, at = ("sitting" if skill == "sit" else "lying"), (cat, inst)
        elif skill == "getup":
            pose = "standing"
            if cat:
                at = (cat, inst)
        elif skill == "reach":
            at = (cat, inst)
    return pose, at


def semantic_errors(keyframes: Sequence[Any], start_pose: str = "standing",
                    start_at: tuple[str, int] | None = None, path: str = "keyframes") -> list[str]:
    """Violations of the pose rules (module docstring, rules 1-7) by ``keyframes``.

    ``keyframes`` are dicts or :class:`~stairenv.screenplays.database.Keyframe` objects;
    ``start_pose``/``start_at`` give the character's state before the first keyframe.
    """
    errors: list[str] = []
    pose, at = start_pose, start_at
    if start_pose != "standing":
        first = keyframes[0] if keyframes else None
        if first is None or _kf_get(first, "skill") != "getup" or not _kf_get(first, "furniture"):
            errors.append(f"{path}[0].skill: a script that starts {start_pose} must begin with a getup "
                          "from a named furniture")
        else:
            skill = {"sitting": "sit", "lying": "lie"}.get(start_pose)
            cat = _kf_get(first, "furniture")
            if skill is not None and cat in FURNITURE and cat not in AFFORDANCES[skill]:
                errors.append(f"{path}[0].furniture: a script that starts {start_pose} gets up from what one can "
                              f"{skill} on ({sorted(AFFORDANCES[skill])}), not a {cat}")
            if at is None:
                at = (cat, int(_kf_get(first, "instance", 0) or 0))
    for i, kf in enumerate(keyframes):
        p = f"{path}[{i}]"
        skill = _kf_get(kf, "skill")
        cat = _kf_get(kf, "furniture")
        inst = int(_kf_get(kf, "instance", 0) or 0)
        part = _kf_get(kf, "part")
        hand = _kf_get(kf, "hand")
        if skill not in SKILLS:
            errors.append(f"{p}.skill: {_show(skill)} is not one of {list(SKILLS)}")
            continue
        if cat is not None and cat in FURNITURE and cat not in AFFORDANCES[skill]:
            errors.append(f"{p}.furniture: cannot {skill} on a {cat} "
                          f"(possible: {sorted(AFFORDANCES[skill])})")
        if part is not None:
            if part not in SKILL_PARTS[skill]:
                allowed = sorted(SKILL_PARTS[skill])
                errors.append(f"{p}.part: {skill} takes no part {_show(part)}"
                              + (f" (possible: {allowed})" if allowed else " (it takes none)"))
            elif cat in FURNITURE_PARTS and part not in FURNITURE_PARTS[cat]:
                errors.append(f"{p}.part: a {cat} has no {part!r} (it has {sorted(FURNITURE_PARTS[cat])})")
        if hand is not None and skill != "reach":
            errors.append(f"{p}.hand: only a reach keyframe takes a hand, not {skill}")

        if skill == "walk":
            if pose != "standing":
                errors.append(f"{p}.skill: walk while {pose} on {_label(*at) if at else 'something'}; "
                              "a getup must come first")
            pose, at = "standing", ((cat, inst) if cat else None)
        elif skill in INTERACTIONS:
            if cat is None:
                errors.append(f"{p}.furniture: {skill} needs a furniture")
            elif pose != "standing":
                errors.append(f"{p}.skill: {skill} on {_label(cat, inst)} while {pose} "
                              f"on {_label(*at) if at else 'something'}; a getup must come first")
            elif at != (cat, inst):
                errors.append(f"{p}.skill: {skill} on {_label(cat, inst)} must be preceded by a walk to "
                              f"{_label(cat, inst)} (the character is at {_label(*at) if at else 'no furniture'})")
            if skill == "sit":
                pose = "sitting"
            elif skill == "lie":
                pose = "lying"
            if cat is not None:
                at = (cat, inst)
        elif skill == "getup":
            if pose == "standing":
                errors.append(f"{p}.skill: getup must follow a sit or lie (the character is standing)")
            elif cat is not None and at is not None and (cat, inst) != at:
                errors.append(f"{p}.furniture: getup from {_label(cat, inst)} but the character is {pose} "
                              f"on {_label(*at)}")
            pose = "standing"
            if cat is not None:
                at = (cat, inst)
    return errors


def keyframe_sequence_errors(keyframes: Sequence[Any], start_pose: str = "standing",
                             start_at: tuple[str, int] | None = None) -> list[str]:
    """Errors of keyframe dicts run in a row (a story's): each against :data:`KEYFRAME_SCHEMA`,
    then, when they all conform, the pose rules of :func:`semantic_errors`."""
    errors = [e for i, kf in enumerate(keyframes) for e in validate_instance(kf, KEYFRAME_SCHEMA, f"keyframes[{i}]")]
    return errors or semantic_errors(keyframes, start_pose=start_pose, start_at=start_at)


def script_errors(script: Any, semantic: bool = True) -> list[str]:
    """All errors of a script dict: schema first; semantic rules only when the schema holds."""
    errors = schema_errors(script)
    if errors or not semantic:
        return errors
    return semantic_errors(script["keyframes"], start_pose=script.get("start_pose", "standing"))


def validate_script(script: Any, semantic: bool = True) -> None:
    """Raise :class:`ScriptValidationError` listing every problem of ``script``."""
    errors = script_errors(script, semantic=semantic)
    if errors:
        sid = script.get("id") if isinstance(script, Mapping) and isinstance(script.get("id"), str) else None
        raise ScriptValidationError(errors, sid)
