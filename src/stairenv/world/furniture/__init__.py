"""Parametric furniture (SIMS): families of convex parts with labels for contact goals.

SIMS (Sec. 3.3, supplement) makes a character sit, lie and reach on furniture: the
contact goal of a joint is "the nearest point of the target part" (seat, backrest,
armrest, bed surface, table top, shelf, ...). Here every piece of furniture is a set of
convex ``Part``\\ s, each with such a label, generated from a frozen config of parameter
ranges by ``make_furniture(family, rng, **overrides)`` (pure: the same rng state gives the
same piece). Because each part is convex, MuJoCo collides with the exact shape (one box or
mesh geom per part): a chair is a seat, four legs and a backrest, not one hull that fills
the space under the seat and in front of the backrest.

Frames and units
----------------
Furniture frame: z up, the front (where a person sits, lies down from, or opens the doors)
faces +x, the footprint (the xy bounding box of all parts) is centred on the origin and the
piece stands on z = 0. Lengths in metres, angles in radians unless a name ends in ``_deg``.
A placed piece has a pose (x, y, yaw): the furniture frame turned by ``yaw`` (rad,
counter-clockwise about +z) and moved to (x, y, 0) in the world.

Families (``FAMILIES``) and their part labels
---------------------------------------------
| family | labels |
|---|---|
| chair | seat, backrest, leg |
| armchair | seat, backrest, armrest, base, leg |
| stool | seat, leg |
| sofa | seat (one per cushion), backrest, armrest, base, leg |
| bed, double_bed | bed_surface, headboard, pillow, base, leg, [footboard] |
| table | table_top, leg (rectangular) or pole, base (round) |
| cabinet, wardrobe | body, door, handle, top, base |
| bookshelf | shelf (bottom to top), side, back, [books] |
| lamp | base, pole, lamp_shade |

``bed`` and ``double_bed`` are one generator (``BedConfig``) with a ``size`` parameter
("single" / "double"); the family name follows the size, so a room's layout graph can tell
a double bed from a bed (SIMS substitutes one for the other when retrieving layouts).

MuJoCo
------
``add_furniture_to_spec(spec, furniture, pose, name)`` adds one static body per piece with
one geom per part (boxes as box geoms, other parts as mesh geoms built from the part's
vertices), named ``{name}/{label}/{k}`` (k counts the parts of that label from 0).

Configs
-------
Each family's generator draws from a frozen config of (min, max) ranges (``ChairConfig``,
...). Every config field is declared once, with its default, valid range and meaning beside
it (``ranged`` / ``number`` / ``choice`` in ``fields``); validation and the field tables in
the config docstrings come from those declarations.

What lives where (one module per job)
-------------------------------------
- ``parts``: ``Part`` (one convex piece), ``ContactSurface``, round point sets.
- ``model``: ``Furniture`` (labelled parts in the furniture frame), ``FAMILIES`` and the
  family groups (``SEATING_FAMILIES``, ``LYING_FAMILIES``, ``SUBSTITUTES``, ``TOP_LABELS``).
- ``fields``: ``ranged``, ``number``, ``choice``, ``FurnitureConfig`` (validation) and
  ``config_class`` (frozen dataclass plus the docstring table).
- ``configs``: one config per generator, ``FURNITURE_CONFIGS``, ``furniture_config``.
- ``builders``: the generators (config, rng) -> (parts, params) and ``make_furniture``.
- ``colors``: ``part_rgba``.
- ``placement``: ``PlacedFurniture`` (a piece with a world pose).
- ``mjcf``: ``add_furniture_to_spec`` and ``FurnitureHandle``.

Everything is importable from ``stairenv.world.furniture`` itself.
"""

from stairenv.world.furniture.builders import make_furniture
from stairenv.world.furniture.colors import FAMILY_RGBA, HANDLE_RGBA, part_rgba
from stairenv.world.furniture.configs import (
    FURNITURE_CONFIGS,
    ArmchairConfig,
    BedConfig,
    BookshelfConfig,
    CabinetConfig,
    ChairConfig,
    LampConfig,
    SofaConfig,
    StoolConfig,
    TableConfig,
    WardrobeConfig,
    furniture_config,
)
from stairenv.world.furniture.fields import FieldSpec, FurnitureConfig, choice, config_class, number, ranged
from stairenv.world.furniture.mjcf import FurnitureHandle, add_furniture_to_spec
from stairenv.world.furniture.model import (
    FAMILIES,
    LYING_FAMILIES,
    SEATING_FAMILIES,
    SUBSTITUTES,
    TOP_LABELS,
    Furniture,
)
from stairenv.world.furniture.parts import ROUND_SEGMENTS, ContactSurface, Part, cylinder_points, rounded_bar_points
from stairenv.world.furniture.placement import PlacedFurniture

__all__ = [
    "FAMILIES", "FAMILY_RGBA", "FURNITURE_CONFIGS", "HANDLE_RGBA", "LYING_FAMILIES", "ROUND_SEGMENTS",
    "SEATING_FAMILIES", "SUBSTITUTES", "TOP_LABELS", "ArmchairConfig", "BedConfig", "BookshelfConfig",
    "CabinetConfig", "ChairConfig", "ContactSurface", "FieldSpec", "Furniture", "FurnitureConfig",
    "FurnitureHandle", "LampConfig", "Part", "PlacedFurniture", "SofaConfig", "StoolConfig", "TableConfig",
    "WardrobeConfig", "add_furniture_to_spec", "choice", "config_class", "cylinder_points", "furniture_config",
    "make_furniture", "number", "part_rgba", "ranged", "rounded_bar_points",
]
