"""``generate_room(config, rng)`` and ``generate_house(config, rng, num_rooms)``: walls,
doors and furnishing."""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence

import numpy as np

from stairenv.validation import check_choice, check_number
from stairenv.world.furniture import FAMILIES
from stairenv.world.rooms.config import ROOM_TYPES, RoomConfig
from stairenv.world.rooms.doors import Door
from stairenv.world.rooms.model import House, Room
from stairenv.world.rooms.placement import furnish
from stairenv.world.scenes import Box


def _walls_of_cell(cell: Sequence[float], doors: Sequence[Door], t: float, height: float) -> list[Box]:
    """Wall boxes on the 4 edges of ``cell`` (wall centre lines), with door gaps, corners closed."""
    cx0, cy0, cx1, cy1 = cell
    boxes = []
    edges = (((cx0, cy0), (cx1, cy0), 1), ((cx0, cy1), (cx1, cy1), 1), ((cx0, cy0), (cx0, cy1), 0), ((cx1, cy0), (cx1, cy1), 0))
    for (ax, ay), (bx, by), axis in edges:
        along = 0 if axis == 1 else 1  # coordinate that varies along the wall
        line = ay if axis == 1 else ax
        start, end = ((ax, bx) if along == 0 else (ay, by))
        cuts = sorted((d.center[along] - 0.5 * d.width, d.center[along] + 0.5 * d.width) for d in doors
                      if d.axis == (1 - along) and abs(d.center[1 - along] - line) < 1e-6
                      and start < d.center[along] < end)
        pieces, cursor = [], start - 0.5 * t
        for lo, hi in cuts:
            pieces.append((cursor, lo))
            cursor = hi
        pieces.append((cursor, end + 0.5 * t))
        for lo, hi in pieces:
            if hi - lo < 1e-6:
                continue
            mid = 0.5 * (lo + hi)
            if along == 0:
                boxes.append(Box((mid, line), (0.5 * (hi - lo), 0.5 * t), 0.0, 0.0, height))
            else:
                boxes.append(Box((line, mid), (0.5 * t, 0.5 * (hi - lo)), 0.0, 0.0, height))
    return boxes


def _template(cfg: RoomConfig, rng: np.random.Generator, room_type: str) -> tuple[list[str], list[str]]:
    template = ROOM_TYPES[room_type]
    required = [opts[int(rng.integers(0, len(opts)))] for opts in template.required]
    n = int(rng.integers(cfg.num_optional[0], cfg.num_optional[1] + 1))
    n = min(n, len(template.optional))
    picks = rng.choice(len(template.optional), size=n, replace=False) if n else []
    return required, [template.optional[int(k)] for k in picks]


def _check_categories(categories: Iterable[str]) -> list[str]:
    cats = list(categories)
    for c in cats:
        check_choice("categories", c, FAMILIES)
    return cats


def _room_door(cfg: RoomConfig, rng: np.random.Generator, cell: Sequence[float], width: float,
               side: str, rooms: tuple[str, ...]) -> Door | None:
    cx0, cy0, cx1, cy1 = cell
    t = cfg.wall_thickness
    along_lo, along_hi = ((cy0, cy1) if side in ("west", "east") else (cx0, cx1))
    lo, hi = along_lo + t + 0.5 * width + 0.1, along_hi - t - 0.5 * width - 0.1
    if hi < lo:
        return None
    s = float(rng.uniform(lo, hi))
    if side == "west":
        return Door((cx0, s), width, 0, rooms)
    if side == "east":
        return Door((cx1, s), width, 0, rooms)
    if side == "south":
        return Door((s, cy0), width, 1, rooms)
    return Door((s, cy1), width, 1, rooms)


def generate_room(config: RoomConfig, rng: np.random.Generator, categories: Sequence[str] | None = None, *,
                  room_type: str | None = None, name: str = "room",
                  center: Sequence[float] = (0.0, 0.0)) -> Room:
    """A furnished room with one door (to "outside"), interior centred at ``center`` (x, y).

    Without ``categories``: a ``room_type`` (default: drawn from ``config.room_types``)
    gives the required pieces and up to ``config.num_optional`` optional ones (dropped if
    they do not fit). With ``categories`` (family names, repeats allowed): exactly those,
    every one placed (``room_type`` defaults to "custom"); if they do not fit in rooms drawn
    from the config, the largest configured room is tried, then ``RuntimeError``.
    Pure: the same rng state gives the same room. Instance names: ``{family}_{k}``.
    """
    if categories is not None:
        cats = _check_categories(categories)
        room_type = "custom" if room_type is None else room_type
    if room_type is not None and room_type != "custom":
        check_choice("room_type", room_type, tuple(ROOM_TYPES))
    cx, cy = (float(v) for v in center)
    t = cfg_t = config.wall_thickness
    for attempt in range(config.max_attempts):
        big = categories is not None and attempt >= config.max_attempts // 2
        sx = config.size_x[1] if big else float(rng.uniform(*config.size_x))
        sy = config.size_y[1] if big else float(rng.uniform(*config.size_y))
        bounds = (cx - sx / 2, cy - sy / 2, cx + sx / 2, cy + sy / 2)
        cell = (bounds[0] - t / 2, bounds[1] - t / 2, bounds[2] + t / 2, bounds[3] + t / 2)
        rtype = room_type if room_type is not None else config.room_types[int(rng.integers(0, len(config.room_types)))]
        if categories is not None:
            required, optional = cats, []
        else:
            required, optional = _template(config, rng, rtype)
        side = ("west", "east", "south", "north")[int(rng.integers(0, 4))]
        door = _room_door(config, rng, cell, float(rng.uniform(*config.door_width)), side, (name, "outside"))
        if door is None:
            continue
        placed = furnish(config, rng, bounds, [door], required, optional, "")
        if placed is None:
            continue
        walls = tuple(_walls_of_cell(cell, [door], cfg_t, config.wall_height))
        return Room(name, rtype, bounds, walls, (door,), tuple(placed), config.wall_height, cfg_t,
                    config.body_radius, config.reach_distance, config.cell_size)
    raise RuntimeError(f"generate_room: could not place {categories if categories is not None else 'the template'} "
                       f"in {config.max_attempts} rooms of size_x {config.size_x}, size_y {config.size_y}; "
                       f"allow larger rooms, fewer pieces or a smaller clearance / body_radius")


def generate_house(config: RoomConfig, rng: np.random.Generator, num_rooms: int = 3, *,
                   room_types: Sequence[str] | None = None, categories: Sequence[Sequence[str]] | None = None,
                   extra_door_probability: float = 0.25, entrance: bool = True) -> House:
    """``num_rooms`` furnished rooms on a grid, joined through doors in their shared walls.

    Rooms fill a grid of ceil(sqrt(n)) columns row by row; each column has a width drawn
    from ``config.size_x``, each row a depth from ``size_y``, so neighbours share whole
    walls (one wall, ``wall_thickness`` thick, on the shared line). A random spanning tree
    of the neighbours gets one door per edge, other neighbour pairs one with
    ``extra_door_probability``; ``entrance`` adds a door to "outside" on an outer wall.
    ``room_types`` (one per room) and ``categories`` (one list per room, as in
    ``generate_room``) fix the rooms' contents. Rooms are named ``{room_type}{k}``;
    instance names ``{room name}_{family}_{j}``. Pure given ``rng``.
    """
    if not isinstance(num_rooms, (int, np.integer)) or not 1 <= num_rooms <= 64:
        raise ValueError(f"num_rooms must be an integer in [1, 64], got {num_rooms!r}")
    check_number("extra_door_probability", extra_door_probability, 0.0, 1.0)
    if room_types is not None:
        if len(room_types) != num_rooms:
            raise ValueError(f"room_types must name {num_rooms} rooms, got {len(room_types)}")
        for r in room_types:
            if r != "custom":
                check_choice("room_types", r, tuple(ROOM_TYPES))
    if categories is not None:
        if len(categories) != num_rooms:
            raise ValueError(f"categories must hold {num_rooms} lists, got {len(categories)}")
        categories = [_check_categories(c) for c in categories]
    cols = math.ceil(math.sqrt(num_rooms))
    rows = math.ceil(num_rooms / cols)
    t = config.wall_thickness
    cells_ij = [(k // cols, k % cols) for k in range(num_rooms)]
    for attempt in range(config.max_attempts):
        big = categories is not None and attempt >= config.max_attempts // 2
        widths = [config.size_x[1] if big else float(rng.uniform(*config.size_x)) for _ in range(cols)]
        depths = [config.size_y[1] if big else float(rng.uniform(*config.size_y)) for _ in range(rows)]
        xs = np.concatenate(([0.0], np.cumsum(np.array(widths) + t)))
        ys = np.concatenate(([0.0], np.cumsum(np.array(depths) + t)))
        xs -= 0.5 * xs[-1]
        ys -= 0.5 * ys[-1]
        cells = [(xs[j], ys[i], xs[j + 1], ys[i + 1]) for i, j in cells_ij]
        if room_types is not None:
            types = list(room_types)
        elif categories is not None:
            types = ["custom"] * num_rooms
        else:
            pool = list(config.room_types)
            order = [pool[int(k)] for k in rng.permutation(len(pool))]
            types = [order[k % len(order)] for k in range(num_rooms)]
        names = []
        seen: dict[str, int] = {}
        for rt in types:
            names.append(f"{rt}{seen.get(rt, 0)}")
            seen[rt] = seen.get(rt, 0) + 1
        index = {ij: k for k, ij in enumerate(cells_ij)}
        pairs = []
        for k, (i, j) in enumerate(cells_ij):
            for di, dj in ((0, 1), (1, 0)):
                other = index.get((i + di, j + dj))
                if other is not None:
                    pairs.append((k, other, "east" if dj else "north"))
        # A random spanning tree (Kruskal on shuffled edges), then extra doors.
        parent = list(range(num_rooms))
        doors: list[Door] = []
        ok = True
        for e in rng.permutation(len(pairs)):
            a, b, side = pairs[int(e)]
            ra, rb = _find(parent, a), _find(parent, b)
            tree = ra != rb
            if tree:
                parent[ra] = rb
            if tree or rng.uniform() < extra_door_probability:
                width = float(rng.uniform(*config.door_width))
                door = _room_door(config, rng, cells[a], width, side, (names[a], names[b]))
                if door is None:
                    ok = False
                    break
                doors.append(door)
        if not ok:
            continue
        if entrance:
            outer = [(k, s) for k, (i, j) in enumerate(cells_ij) for s, nb in
                     (("west", (i, j - 1)), ("east", (i, j + 1)), ("south", (i - 1, j)), ("north", (i + 1, j)))
                     if nb not in index]
            k, s = outer[int(rng.integers(0, len(outer)))]
            door = _room_door(config, rng, cells[k], float(rng.uniform(*config.door_width)), s, (names[k], "outside"))
            if door is not None:
                doors.append(door)
        rooms = []
        for k in range(num_rooms):
            cell = cells[k]
            bounds = (cell[0] + t / 2, cell[1] + t / 2, cell[2] - t / 2, cell[3] - t / 2)
            room_doors = [d for d in doors if names[k] in d.rooms]
            placed = None
            for _ in range(5):
                if categories is not None:
                    required, optional = list(categories[k]), []
                elif types[k] == "custom":
                    required, optional = [], []
                else:
                    required, optional = _template(config, rng, types[k])
                placed = furnish(config, rng, bounds, room_doors, required, optional, f"{names[k]}_")
                if placed is not None:
                    break
            if placed is None:
                break
            walls = tuple(_walls_of_cell(cell, room_doors, t, config.wall_height))
            rooms.append(Room(names[k], types[k], bounds, walls, tuple(room_doors), tuple(placed),
                              config.wall_height, t, config.body_radius, config.reach_distance, config.cell_size))
        if len(rooms) < num_rooms:
            continue
        all_walls = _unique_walls([w for r in rooms for w in r.walls])
        lo = np.min([r.bounds[:2] for r in rooms], axis=0)
        hi = np.max([r.bounds[2:] for r in rooms], axis=0)
        house = House("house", "house", (float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])), tuple(all_walls),
                      tuple(doors), tuple(f for r in rooms for f in r.furniture), config.wall_height, t,
                      config.body_radius, config.reach_distance, config.cell_size, tuple(rooms))
        if house.is_connected():
            return house
    raise RuntimeError(f"generate_house: no house of {num_rooms} rooms after {config.max_attempts} attempts; "
                       f"allow larger rooms or fewer pieces")


def _find(parent: list[int], a: int) -> int:
    """Union-find root of ``a`` (with path halving)."""
    while parent[a] != a:
        parent[a] = parent[parent[a]]
        a = parent[a]
    return a


def _unique_walls(walls: Iterable[Box]) -> list[Box]:
    out: list[Box] = []
    keys = set()
    for w in walls:
        key = tuple(round(v, 6) for v in (*w.center, *w.half_size, w.yaw, w.bottom, w.top))
        if key not in keys:
            keys.add(key)
            out.append(w)
    return out
