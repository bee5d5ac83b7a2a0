"""SIMS script planning: short scripts, long-story assembly and room retrieval.

Named ``screenplays`` (what a character is to act out; :mod:`stairenv.stories` acts it) so that
"scripts" means only the runnable ones in ``baselines/``; ``stairenv.scripts`` is the old name, a
deprecated alias for one release.

* :mod:`~stairenv.screenplays.schema` - the short-script JSON Schema, a validator whose errors
  name the bad field, and the pose rules a keyframe sequence must follow;
* :mod:`~stairenv.screenplays.database` - :class:`Script`/:class:`Keyframe` and the shipped
  database of 48 short scripts (``data/*.json``; 8 styles x 6, all 5 skills, all three
  difficulty buckets);
* :mod:`~stairenv.screenplays.embeddings` - offline text encoders (packaged MiniLM, hashing,
  any callable such as CLIP), reduction to a configurable size, a disk + memory cache;
* :mod:`~stairenv.screenplays.story` - :func:`assemble_story` (theme -> ordered scripts), the
  optional :class:`LLMBackend`;
* :mod:`~stairenv.screenplays.retrieval` - layout graphs, :func:`required_furniture`,
  :func:`retrieve_room` by graph edit distance with substitutions and a fallback builder.

Example::

    from stairenv.screenplays import load_database, get_encoder, assemble_story, retrieve_room
    db = load_database()
    story = assemble_story("a tired evening at home", db, get_encoder("auto"), length=3)
    match = retrieve_room(story, rooms, fallback=lambda cats: generate_room(cfg, rng, categories=cats))
    for keyframe, room_node in bind_keyframes(story.keyframes, match): ...

Importing this package does not import torch or sentence-transformers; the MiniLM model
loads on first use. Acting a script out in a room (the state machine, the kinematic stand-in)
is :mod:`stairenv.stories`, which builds on this package.
"""

from stairenv.screenplays.database import (
    DATA_DIR,
    DIFFICULTIES,
    Keyframe,
    Script,
    ScriptDatabase,
    ScriptFileError,
    difficulty_of,
    load_database,
)
from stairenv.screenplays.embeddings import (
    CachedEncoder,
    CallableEncoder,
    EncoderUnavailableError,
    HashingEncoder,
    MiniLMEncoder,
    RandomProjection,
    ReducedEncoder,
    SubspaceProjection,
    TextEncoder,
    corpus_digest,
    cosine_similarity,
    default_cache_dir,
    embeddings_match,
    fit_reduction,
    get_encoder,
    minilm_available,
    reduction_corpus,
    shipped_basis,
    shipped_projection,
)
from stairenv.screenplays.retrieval import (
    DEFAULT_SUBSTITUTIONS,
    GEDCosts,
    NoRoomFoundError,
    RoomIndex,
    RoomMatch,
    bind_keyframes,
    layout_graph_of,
    merge_layout_graphs,
    random_layout_graph,
    required_furniture,
    retrieve_room,
    script_layout_graph,
    world_room_builder,
)
from stairenv.screenplays.schema import (
    FURNITURE,
    INTERACTIONS,
    SCRIPT_SCHEMA,
    SKILLS,
    STYLES,
    ScriptValidationError,
    schema_errors,
    script_errors,
    semantic_errors,
    validate_script,
)
from stairenv.screenplays.story import (
    CompletionLLM,
    LLMBackend,
    NoLLM,
    Story,
    assemble_story,
    chain_scripts,
    transition,
)

__all__ = [
    "DATA_DIR",
    "DEFAULT_SUBSTITUTIONS",
    "DIFFICULTIES",
    "FURNITURE",
    "INTERACTIONS",
    "SCRIPT_SCHEMA",
    "SKILLS",
    "STYLES",
    "CachedEncoder",
    "CallableEncoder",
    "CompletionLLM",
    "EncoderUnavailableError",
    "GEDCosts",
    "HashingEncoder",
    "Keyframe",
    "LLMBackend",
    "MiniLMEncoder",
    "NoLLM",
    "NoRoomFoundError",
    "RandomProjection",
    "ReducedEncoder",
    "RoomIndex",
    "RoomMatch",
    "Script",
    "ScriptDatabase",
    "ScriptFileError",
    "ScriptValidationError",
    "Story",
    "SubspaceProjection",
    "TextEncoder",
    "assemble_story",
    "bind_keyframes",
    "chain_scripts",
    "corpus_digest",
    "cosine_similarity",
    "default_cache_dir",
    "difficulty_of",
    "embeddings_match",
    "fit_reduction",
    "get_encoder",
    "layout_graph_of",
    "load_database",
    "merge_layout_graphs",
    "minilm_available",
    "random_layout_graph",
    "reduction_corpus",
    "required_furniture",
    "retrieve_room",
    "schema_errors",
    "script_errors",
    "script_layout_graph",
    "semantic_errors",
    "shipped_basis",
    "shipped_projection",
    "transition",
    "validate_script",
    "world_room_builder",
]
