"""Plot training curves of ``train_ppo.py`` runs from their TensorBoard logs, against steps and wall time.

    python baselines/plot_training.py stairs=runs/ab_stairs/InterLevel-v0/seed0 \
        plain=runs/ab_plain/InterLevel-v0/seed0 --out docs/interlevel_training.png

Each run is ``LABEL=FOLDER`` (every ``events.out.tfevents*`` below the folder, a resumed run's too).
Panels: episode length, progress / success / falls of the episodes that started on the floor
(``episode_floor_start/*``, comparable with the evaluation; ``episode/*`` for runs without them),
the style reward and, for runs with a step-height curriculum, its mean level. Values are averaged
over ``--bins`` equal step windows (the per-episode scalars are noisy: a rollout ends only a few
episodes). The top row is against env steps, the bottom row against hours of training (wall time
from the first logged value of each run).
A table of the same windows is printed.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

PANELS = (
    ("rollout/ep_len_mean", "episode/length", "episode length (steps of 1/30 s)"),
    ("episode_floor_start/progress", "episode/progress", "progress, floor starts"),
    ("episode_floor_start/success", "episode/success", "success, floor starts"),
    ("episode_floor_start/fell", "episode/fell", "falls, floor starts"),
    ("amp/style_reward", None, "style reward (training discriminator)"),
    ("curriculum/level", None, "step-height curriculum level (mean)"),
)


def read_scalars(folder: Path) -> dict[str, np.ndarray]:
    """Every scalar tag below ``folder``: rows (step, value, wall time), sorted by step."""
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    series: dict[str, list] = {}
    files = sorted(folder.rglob("events.out.tfevents*"))
    if not files:
        raise SystemExit(f"no TensorBoard logs (events.out.tfevents*) below {folder}")
    for path in files:
        events = EventAccumulator(str(path), size_guidance={"scalars": 0})
        events.Reload()
        for tag in events.Tags()["scalars"]:
            series.setdefault(tag, []).extend((e.step, e.value, e.wall_time) for e in events.Scalars(tag))
    return {tag: np.array(sorted(rows)) for tag, rows in series.items()}


def binned(rows: np.ndarray, bins: int) -> np.ndarray:
    """(window end step, mean value, mean wall time) of ``bins`` equal step windows with data."""
    edges = np.linspace(rows[0, 0], rows[-1, 0] + 1, bins + 1)
    out = []
    for low, high in zip(edges[:-1], edges[1:]):
        inside = (rows[:, 0] >= low) & (rows[:, 0] < high)
        if inside.any():
            out.append((rows[inside, 0].max(), rows[inside, 1].mean(), rows[inside, 2].mean()))
    return np.array(out)


def main(argv: list[str] | None = None) -> Path:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("runs", nargs="+", metavar="LABEL=FOLDER")
    p.add_argument("--out", type=Path, default=Path("training.png"))
    p.add_argument("--bins", type=int, default=20)
    args = p.parse_args(argv)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    runs = []
    for item in args.runs:
        label, sep, folder = item.partition("=")
        if not sep:
            raise SystemExit(f"expected LABEL=FOLDER, got {item!r}")
        runs.append((label, read_scalars(Path(folder))))
    fig, axes = plt.subplots(2, len(PANELS), figsize=(4 * len(PANELS), 6.5), squeeze=False)
    for column, (tag, fallback, title) in enumerate(PANELS):
        for index, (label, scalars) in enumerate(runs):  # one colour per run in every panel, tag or not
            rows = scalars.get(tag, scalars.get(fallback)) if fallback else scalars.get(tag)
            if rows is None or len(rows) == 0:
                continue
            start = min(series[0, 2] for series in scalars.values())
            curve = binned(rows, args.bins)
            axes[0, column].plot(curve[:, 0] / 1e6, curve[:, 1], label=label, color=f"C{index % 10}")
            axes[1, column].plot((curve[:, 2] - start) / 3600.0, curve[:, 1], label=label, color=f"C{index % 10}")
            print(f"{label:12s} {tag:30s} " + " ".join(f"{s / 1e6:.1f}M:{v:.3f}" for s, v, _ in curve))
        axes[0, column].set_title(title, fontsize=9)
        axes[0, column].set_xlabel("env steps (M)")
        axes[1, column].set_xlabel("hours of training")
    fig.legend(*axes[0, 0].get_legend_handles_labels(), loc="lower center", ncol=len(runs), fontsize=8)
    fig.tight_layout(rect=(0, 0.05, 1, 1))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=80)
    print(f"wrote {args.out}")
    return args.out


if __name__ == "__main__":
    main()
