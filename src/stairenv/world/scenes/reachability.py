"""Which cells of a planning grid a character can move between (``connected_free_space``)."""

from __future__ import annotations

import numpy as np
from scipy import ndimage
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from stairenv.planning.grid import PlanningGrid


# --- reachability --------------------------------------------------------------------------------
def connected_free_space(grid: PlanningGrid, *, max_step_height: float = 0.25, min_clearance: float = 0.5,
                         body_radius: float = 0.25) -> np.ndarray:
    """Label the cells a character can move between (4-connected), largest region first.

    A cell is free if its centre lies more than ``body_radius`` (m) from the centre of
    every blocked cell and the ceiling above it leaves at least ``min_clearance`` (m, a
    crawl). Two neighbouring free cells connect if their heights differ by at most
    ``max_step_height`` (m). Returns (H, W) int labels: 0 for the largest connected
    region, 1 for the next, ...; -1 where not free.
    """
    rows, cols = grid.shape
    c = grid.cell_size
    if grid.blocked.any():
        to_blocked = ndimage.distance_transform_edt(~grid.blocked) * c
    else:
        to_blocked = np.full(grid.shape, np.inf)
    free = (to_blocked > body_radius) & (grid.ceiling - grid.heights >= min_clearance)
    index = np.arange(rows * cols).reshape(rows, cols)
    h = grid.heights
    join_x = free[:, 1:] & free[:, :-1] & (np.abs(h[:, 1:] - h[:, :-1]) <= max_step_height)
    join_y = free[1:, :] & free[:-1, :] & (np.abs(h[1:, :] - h[:-1, :]) <= max_step_height)
    src = np.concatenate((index[:, :-1][join_x], index[:-1, :][join_y]))
    dst = np.concatenate((index[:, 1:][join_x], index[1:, :][join_y]))
    graph = coo_matrix((np.ones(len(src), dtype=np.int8), (src, dst)), shape=(rows * cols, rows * cols))
    count, labels = connected_components(graph, directed=False)
    labels = labels.reshape(rows, cols)
    sizes = np.bincount(labels[free], minlength=count)
    rank = np.empty(count, dtype=np.int64)
    rank[np.argsort(-sizes, kind="stable")] = np.arange(count)
    return np.where(free, rank[labels], -1)
