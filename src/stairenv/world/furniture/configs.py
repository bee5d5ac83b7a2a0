"""The furniture configs: one frozen dataclass of parameter ranges per family generator.

Every field is declared once, with its default, its valid range and its meaning
(``ranged`` / ``number`` / ``choice``, see ``stairenv.world.furniture.fields``); the tables in
the class docstrings are made from those declarations. Ranges are (min, max) in metres and
degrees; a builder draws each value uniformly from its range.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import fields, replace
from types import MappingProxyType
from typing import Any

from stairenv.validation import check_choice
from stairenv.world.furniture.fields import FurnitureConfig, choice, config_class, number, ranged
from stairenv.world.furniture.model import FAMILIES


@config_class
class ChairConfig(FurnitureConfig):
    """A dining chair: four legs, a seat, a backrest tilted back. Ranges (min, max), metres, degrees."""

    seat_height: tuple[float, float] = ranged((0.42, 0.48), 0.25, 0.9, "top of the seat above the floor")
    seat_width: tuple[float, float] = ranged((0.40, 0.50), 0.3, 0.8, "along y")
    seat_depth: tuple[float, float] = ranged((0.40, 0.48), 0.3, 0.8, "along x")
    seat_thickness: tuple[float, float] = ranged((0.03, 0.06), 0.015, 0.15)
    leg_thickness: tuple[float, float] = ranged((0.03, 0.05), 0.015, 0.1)
    backrest_height: tuple[float, float] = ranged((0.35, 0.50), 0.1, 1.0, "above the seat")
    backrest_thickness: tuple[float, float] = ranged((0.025, 0.05), 0.01, 0.15)
    backrest_tilt_deg: tuple[float, float] = ranged((0.0, 12.0), 0.0, 30.0, "backwards from vertical")


@config_class
class ArmchairConfig(FurnitureConfig):
    """An upholstered armchair: short legs, a base, a seat cushion, a backrest and two armrests."""

    seat_height: tuple[float, float] = ranged((0.42, 0.48), 0.25, 0.9, "top of the cushion")
    seat_width: tuple[float, float] = ranged((0.50, 0.62), 0.35, 1.2, "between the armrests")
    seat_depth: tuple[float, float] = ranged((0.48, 0.58), 0.3, 1.0, "backrest to front edge")
    cushion_thickness: tuple[float, float] = ranged((0.08, 0.14), 0.02, 0.3)
    leg_height: tuple[float, float] = ranged((0.05, 0.14), 0.01, 0.3)
    arm_width: tuple[float, float] = ranged((0.08, 0.18), 0.04, 0.4)
    arm_height: tuple[float, float] = ranged((0.16, 0.24), 0.05, 0.5, "armrest top above the seat")
    back_thickness: tuple[float, float] = ranged((0.12, 0.20), 0.04, 0.4)
    back_height: tuple[float, float] = ranged((0.40, 0.55), 0.1, 1.2, "above the seat")


@config_class
class StoolConfig(FurnitureConfig):
    """A stool: a round or square seat on 3 or 4 legs."""

    seat_height: tuple[float, float] = ranged((0.42, 0.50), 0.25, 0.9)
    seat_radius: tuple[float, float] = ranged((0.16, 0.21), 0.1, 0.4, "radius (round) or half side (square)")
    seat_thickness: tuple[float, float] = ranged((0.03, 0.05), 0.015, 0.15)
    leg_thickness: tuple[float, float] = ranged((0.025, 0.04), 0.015, 0.1)
    num_legs: tuple[int, int] = ranged((3, 4), 3, 6, integer=True)
    round_probability: float = number(0.5, 0.0, 1.0, "chance of a round seat")


@config_class
class SofaConfig(FurnitureConfig):
    """A sofa: short legs, a base, 2-3 seat cushions (each labelled "seat"), backrest, armrests."""

    width: tuple[float, float] = ranged((1.6, 2.4), 1.0, 4.0, "overall, armrests included")
    seat_depth: tuple[float, float] = ranged((0.52, 0.65), 0.3, 1.2)
    seat_height: tuple[float, float] = ranged((0.42, 0.48), 0.25, 0.9)
    cushion_thickness: tuple[float, float] = ranged((0.10, 0.18), 0.02, 0.3)
    leg_height: tuple[float, float] = ranged((0.04, 0.12), 0.01, 0.3)
    arm_width: tuple[float, float] = ranged((0.10, 0.22), 0.04, 0.4)
    arm_height: tuple[float, float] = ranged((0.12, 0.24), 0.05, 0.5, "above the seat")
    back_thickness: tuple[float, float] = ranged((0.15, 0.25), 0.04, 0.5)
    back_height: tuple[float, float] = ranged((0.35, 0.50), 0.1, 1.2, "above the seat")
    num_seats: tuple[int, int] = ranged((2, 3), 1, 6, "cushions", integer=True)


@config_class
class BedConfig(FurnitureConfig):
    """A bed: legs, a frame ("base"), a mattress ("bed_surface"), a headboard at the back (-x),
    pillows at the head end, sometimes a footboard. ``size`` "double" makes a "double_bed"."""

    size: str = choice("single", ("single", "double"))
    single_width: tuple[float, float] = ranged((0.9, 1.2), 0.6, 3.0, "mattress width of a single bed")
    double_width: tuple[float, float] = ranged((1.4, 1.8), 0.6, 3.0, "mattress width of a double bed")
    length: tuple[float, float] = ranged((1.95, 2.15), 1.0, 3.0, "mattress length")
    surface_height: tuple[float, float] = ranged((0.45, 0.58), 0.2, 1.0, "top of the mattress")
    mattress_thickness: tuple[float, float] = ranged((0.15, 0.25), 0.05, 0.5)
    leg_height: tuple[float, float] = ranged((0.05, 0.18), 0.01, 0.4)
    frame_margin: tuple[float, float] = ranged((0.02, 0.05), 0.0, 0.3, "frame beyond the mattress")
    headboard_height: tuple[float, float] = ranged((0.85, 1.2), 0.3, 2.0, "top above the floor")
    headboard_thickness: tuple[float, float] = ranged((0.04, 0.10), 0.01, 0.3)
    pillow_height: tuple[float, float] = ranged((0.08, 0.13), 0.02, 0.3)
    footboard_probability: float = number(0.3, 0.0, 1.0)


@config_class
class TableConfig(FurnitureConfig):
    """A table: a rectangular top on four legs, or a round top on a pedestal ("pole" + "base")."""

    top_height: tuple[float, float] = ranged((0.72, 0.78), 0.3, 1.2, "top surface above the floor")
    top_thickness: tuple[float, float] = ranged((0.025, 0.05), 0.01, 0.15)
    depth: tuple[float, float] = ranged((0.7, 1.0), 0.3, 2.0, "rectangular, along x")
    length: tuple[float, float] = ranged((0.8, 1.8), 0.3, 4.0, "rectangular, along y")
    diameter: tuple[float, float] = ranged((0.7, 1.1), 0.3, 2.0, "round")
    leg_thickness: tuple[float, float] = ranged((0.04, 0.07), 0.015, 0.15)
    leg_inset: tuple[float, float] = ranged((0.03, 0.08), 0.0, 0.3, "from the top's edge")
    round_probability: float = number(0.3, 0.0, 1.0)


@config_class
class CabinetConfig(FurnitureConfig):
    """A closed case: plinth ("base"), "body", "door"s with "handle"s on the front, a "top".

    Defaults describe a sideboard / chest; ``WardrobeConfig`` has the same fields.
    """

    width: tuple[float, float] = ranged((0.5, 1.2), 0.2, 4.0, "along y")
    depth: tuple[float, float] = ranged((0.38, 0.55), 0.15, 1.5, "along x")
    height: tuple[float, float] = ranged((0.6, 1.1), 0.2, 3.0, "top surface")
    plinth_height: tuple[float, float] = ranged((0.04, 0.10), 0.0, 0.3)
    top_thickness: tuple[float, float] = ranged((0.02, 0.04), 0.005, 0.1)
    door_width: tuple[float, float] = ranged((0.35, 0.6), 0.15, 1.5,
                                              "the number of doors is round(width / door_width)")


@config_class
class WardrobeConfig(CabinetConfig):
    """A wardrobe: a tall ``CabinetConfig`` (same fields and ranges, other defaults) with 2-4 doors."""

    width: tuple[float, float] = (0.8, 2.0)
    depth: tuple[float, float] = (0.55, 0.65)
    height: tuple[float, float] = (1.8, 2.2)
    plinth_height: tuple[float, float] = (0.05, 0.10)
    top_thickness: tuple[float, float] = (0.02, 0.05)
    door_width: tuple[float, float] = (0.4, 0.6)


@config_class
class BookshelfConfig(FurnitureConfig):
    """An open bookshelf: two "side"s, a "back", ``num_shelves + 1`` boards labelled "shelf"
    (bottom to top), and blocks of "books" on some shelves."""

    width: tuple[float, float] = ranged((0.6, 1.2), 0.2, 4.0, "along y")
    depth: tuple[float, float] = ranged((0.25, 0.40), 0.1, 1.0, "along x")
    height: tuple[float, float] = ranged((1.2, 2.0), 0.3, 3.0)
    board_thickness: tuple[float, float] = ranged((0.018, 0.03), 0.005, 0.08)
    num_shelves: tuple[int, int] = ranged((3, 6), 1, 12, "compartments", integer=True)
    books_probability: float = number(0.7, 0.0, 1.0, "chance of books in a compartment")


@config_class
class LampConfig(FurnitureConfig):
    """A floor lamp: a round "base", a "pole" and a conical "lamp_shade"."""

    height: tuple[float, float] = ranged((1.4, 1.8), 0.3, 2.5, "top of the shade")
    base_radius: tuple[float, float] = ranged((0.12, 0.20), 0.05, 0.5)
    base_thickness: tuple[float, float] = ranged((0.02, 0.04), 0.005, 0.2)
    pole_radius: tuple[float, float] = ranged((0.012, 0.02), 0.005, 0.1)
    shade_radius: tuple[float, float] = ranged((0.15, 0.24), 0.05, 0.6, "bottom radius")
    shade_taper: tuple[float, float] = ranged((0.55, 0.85), 0.1, 1.0, "top radius / bottom radius")
    shade_height: tuple[float, float] = ranged((0.2, 0.3), 0.05, 0.8)


FURNITURE_CONFIGS: Mapping[str, FurnitureConfig] = MappingProxyType({
    "chair": ChairConfig(), "armchair": ArmchairConfig(), "stool": StoolConfig(), "sofa": SofaConfig(),
    "bed": BedConfig(size="single"), "double_bed": BedConfig(size="double"), "table": TableConfig(),
    "cabinet": CabinetConfig(), "wardrobe": WardrobeConfig(), "bookshelf": BookshelfConfig(),
    "lamp": LampConfig(),
})


def furniture_config(family: str, **overrides: Any) -> FurnitureConfig:
    """The default config of ``family`` with ``overrides`` (a scalar fixes a range: x -> (x, x))."""
    check_choice("family", family, FAMILIES)
    base = FURNITURE_CONFIGS[family]
    names = [f.name for f in fields(base)]
    unknown = sorted(set(overrides) - set(names))
    if unknown:
        raise ValueError(f"{family} has no parameter(s) {unknown}; valid: {names}")
    return replace(base, **overrides) if overrides else base
