"""``python -m stairenv`` (or ``stairenv``): record an MP4 of a policy in an env.

Examples::

    python -m stairenv                                   # one InterLevel-v0 episode -> videos/interlevel.mp4
    python -m stairenv --policy pretrained               # the trained policy shipped with the package
    python -m stairenv --policy random --seconds 3 --frames-png stills/
    python -m stairenv --policy runs/ppo/model.zip --env InterLevel2D-v0 --out videos/2d.mp4
    python -m stairenv --env-kwarg step_height_set="(0.15,)" --env-kwarg random_start_heading=False

Without ``--seconds`` the video shows one episode to its end (success, fall, physics divergence or
the time limit; at most :data:`MAX_EPISODE_SECONDS`) and holds its last frame for a second with the
outcome written on it. With ``--seconds`` it has that length: episodes that end before are followed
by new ones (seeds ``seed``, ``seed + 1``, ...). The follow camera stands
``--camera-distance`` m from the pelvis so that the character fills the frame; each frame carries
the env, the policy and the episode time.

Without ``--policy`` the video shows the trained policy the package ships for the env
(``stairenv/policies/<env id>.npz``, ``stairenv.pretrained.load``) and, where none ships, the
zero policy, with a one-line note saying so. ``--policy pretrained`` asks for the shipped policy
and is an error where none ships.

``--out`` and ``--frames-png`` are checked before anything is rendered (:func:`check_output`: a usage
error naming the flag and the path); the film is written under a hidden name beside ``--out`` and
moved there once whole, so a film that stops leaves no half-written file (nor its stills).
"""

from __future__ import annotations

import argparse
import contextlib
import os
import secrets
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from stairenv.evaluation.cli import env_kwarg_argument
from stairenv.policy_loading import PRETRAINED  # ``--policy`` for the policy shipped with the package

DEFAULT_ENV = "InterLevel-v0"
#: the first episode's seed where ``--seed`` is not given: for InterLevel-v0 a staircase the shipped climber
#: climbs to M_T (measured 2026-12-08: the episode succeeds, and again in 21 of 24 reruns with its actions
#: perturbed by 1e-6 to 1e-4, as another machine's low bits would; the shipped policy succeeds in 57.7% of the
#: paper's 1,000 staircases, the README says), 0 for every other env
DEFAULT_SEEDS = {"InterLevel-v0": 3}
#: what ``--policy`` falls back to when the package ships no trained policy for the env
FALLBACK_POLICY = "zero"
def default_out(env_id: str) -> str:
    """Where a film of ``env_id`` goes unless ``--out`` says: ``videos/<the id's name>.mp4`` (``interlevel.mp4``,
    ``sims-walk.mp4``), so that filming one env does not overwrite another's film."""
    return f"videos/{env_id.rsplit('-v', 1)[0].lower()}.mp4"


#: keywords the film sets itself (``--width``, ``--height``; it renders offscreen)
FILM_KEYWORDS = ("render_mode", "width", "height")
#: a one-episode video stops here if the episode has not ended (envs without a time limit)
MAX_EPISODE_SECONDS = 60.0
#: the follow camera of a film: distance (m) from the pelvis and elevation (deg); a 1.7 m character
#: then fills about two thirds of the frame height
FILM_CAMERA_DISTANCE = 3.2
FILM_CAMERA_ELEVATION = -12.0
#: how long the last frame, with the outcome written on it, is held (s)
OUTCOME_HOLD_SECONDS = 1.0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="stairenv",
        description="Record a short MP4 video of a policy in a stairenv env (offscreen rendering).",
    )
    parser.add_argument("--env", default=DEFAULT_ENV, help="env id (default: %(default)s)")
    parser.add_argument("--policy", default=None,
                        help="'pretrained' (the trained policy shipped for --env), 'random', 'zero', an exported "
                             "policy .npz, a Stable-Baselines3 model .zip or ALGO:path (default: the shipped "
                             f"policy, else {FALLBACK_POLICY!r})")
    parser.add_argument("--seconds", type=float, default=None,
                        help="video length in seconds (default: one episode, filmed to its end)")
    parser.add_argument("--seed", type=int, default=None,
                        help="seed of the first episode (default: 3 for InterLevel-v0, a staircase its shipped "
                             "policy climbs to the end; 0 for the other envs)")
    parser.add_argument("--out", default=None,
                        help="output .mp4 path (default: videos/<env name>.mp4, e.g. videos/interlevel.mp4)")
    parser.add_argument("--width", type=int, default=640, help="frame width in pixels (default: %(default)s)")
    parser.add_argument("--height", type=int, default=480, help="frame height in pixels (default: %(default)s)")
    parser.add_argument("--env-kwarg", action="append", default=[], type=env_kwarg_argument, metavar="KEY=VALUE",
                        help="extra env keyword, repeatable; values parsed as Python literals, else strings")
    parser.add_argument("--camera-distance", type=float, default=FILM_CAMERA_DISTANCE,
                        help="follow camera distance from the pelvis in m (default: %(default)s)")
    parser.add_argument("--frames-png", metavar="DIR", help="also write one PNG still per second of video into DIR")
    parser.add_argument("--policy-captions", action="store_true",
                        help="text-conditioned envs: draw the captions the policy recorded from its training "
                             "(a policy trained on few captions follows unseen ones worse) instead of the env's")
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    return parser


def check_output(flag: str, path: str | os.PathLike, folder: bool = False) -> Path:
    """``path`` as a ``Path`` where a file (``folder`` False) or a folder of files can be written;
    ``ValueError`` naming ``flag`` and ``path`` otherwise: a folder where a file is expected (or a file
    where a folder is), a file in the way of the folders to make, a read-only file, or a place where
    nothing can be created (tried by making and removing an empty folder in the nearest existing one).
    Checked before any work, so that a film or a run is not lost at its end; nothing is left behind."""
    path = Path(path).expanduser()
    what = f"{flag} {str(path)!r}"
    if not str(path).strip():
        raise ValueError(f"{flag}: an empty path")
    if folder and path.exists() and not path.is_dir():
        raise ValueError(f"{what}: is a file, not a folder")
    if not folder and path.is_dir():
        raise ValueError(f"{what}: is a folder; give a file path")
    if not folder and path.exists() and not os.access(path, os.W_OK):
        raise ValueError(f"{what}: the file exists and cannot be overwritten (read-only)")
    existing = path if folder else path.parent
    while not existing.exists():
        if existing.is_symlink():
            raise ValueError(f"{what}: {str(existing)!r} is a broken link")
        existing = existing.parent
    if not existing.is_dir():
        raise ValueError(f"{what}: {str(existing)!r} is a file, so no folder can be made in it")
    try:
        os.rmdir(tempfile.mkdtemp(dir=existing, prefix=".stairenv-check-"))
    except OSError as error:
        raise ValueError(f"{what}: nothing can be written in {str(existing)!r} ({error.strerror or error})") from None
    return path


def _make_folders(folder: Path) -> list[Path]:
    """``mkdir -p folder``; the folders it made, innermost first."""
    made = []
    probe = folder
    while not probe.exists():
        made.append(probe)
        probe = probe.parent
    folder.mkdir(parents=True, exist_ok=True)
    return made


def _remove_folders(made: list[Path]) -> None:
    for folder in made:
        with contextlib.suppress(OSError):  # not empty: something else was put there meanwhile
            folder.rmdir()


@contextlib.contextmanager
def written_whole(path: Path) -> Iterator[Path]:
    """A path beside ``path`` (a hidden name, the same suffix) to write ``path``'s content into: moved
    to ``path`` when the block ends, removed (with the folders made for it) when it raises, so that
    no half-written file is left at ``path``. Its folders are made first."""
    made = _make_folders(path.parent)
    partial = path.with_name(f".{path.stem}.{os.getpid()}-{secrets.token_hex(4)}.partial{path.suffix}")
    try:
        yield partial
        os.replace(partial, path)
    except BaseException:
        with contextlib.suppress(OSError):
            partial.unlink()
        _remove_folders(made)
        raise


def check_env_id(env_id: str) -> None:
    """``ValueError`` naming the registered ids unless ``env_id`` is one."""
    import gymnasium as gym

    import stairenv

    if env_id not in gym.registry:
        raise ValueError(f"env must be a registered env id such as {list(stairenv.ENV_IDS)}, got {env_id!r}")


def resolve_policy(policy: str | None, env_id: str) -> tuple[str, str | None]:
    """The policy spec for ``load_policy`` and a one-line note to show (None for none).

    None: the policy shipped for ``env_id`` if the package ships one, else :data:`FALLBACK_POLICY`
    with a note saying that none ships yet. :data:`PRETRAINED`: the shipped policy, ``ValueError``
    where none ships. Anything else is returned as it is.
    """
    from stairenv import pretrained

    if policy is not None and policy != PRETRAINED:
        return policy, None
    path = pretrained.shipped_policy_path(env_id)
    if path.is_file():
        return str(path), f"policy: the trained {env_id} policy shipped with stairenv ({path.name})"
    if policy == PRETRAINED:
        raise ValueError(f"policy {PRETRAINED!r}: no trained policy for {env_id!r} ships with stairenv yet; "
                         "train one with baselines/train_ppo.py and export it with baselines/export_policy.py")
    return FALLBACK_POLICY, (f"note: no trained policy for {env_id} ships with stairenv yet; "
                             f"showing the {FALLBACK_POLICY!r} policy (choose one with --policy)")


def outcome_of(info: dict, terminated: bool, truncated: bool) -> str:
    """How an episode ended, in words: "success", "fell", "lost the path" (PlaMo), "physics diverged",
    "time limit", "ended" (another termination) or "still running"."""
    if info.get("physics_unstable"):
        return "physics diverged"
    if info.get("success"):
        return "success"
    if info.get("fell"):
        return "fell"
    if info.get("off_path"):
        return "lost the path"
    if truncated:
        return "time limit"
    return "ended" if terminated else "still running"


def caption_frame(frame, lines: list[str], banner: str | None = None):
    """``frame`` with ``lines`` written small at its top left and ``banner`` (if any) large across
    its lower third, each on a dark band so that it reads on any background."""
    import numpy as np
    from PIL import Image, ImageDraw, ImageFont

    image = Image.fromarray(frame)
    draw = ImageDraw.Draw(image, "RGBA")
    height = image.height
    small = ImageFont.load_default(size=max(8, height // 30))
    y = 4
    for line in lines:
        box = draw.textbbox((6, y), line, font=small)
        draw.rectangle((box[0] - 3, box[1] - 2, box[2] + 3, box[3] + 2), fill=(0, 0, 0, 140))
        draw.text((6, y), line, font=small, fill=(255, 255, 255, 255))
        y = box[3] + 5
    if banner:
        large = ImageFont.load_default(size=max(10, height // 12))
        box = draw.textbbox((0, 0), banner, font=large)
        x = (image.width - (box[2] - box[0])) // 2
        y = int(height * 0.72)
        draw.rectangle((0, y + box[1] - 8, image.width, y + box[3] + 8), fill=(0, 0, 0, 170))
        draw.text((x, y), banner, font=large, fill=(255, 255, 255, 255))
    return np.asarray(image)


def record(
    env_id: str = DEFAULT_ENV,
    policy: str | None = None,
    seconds: float | None = None,
    seed: int = 0,
    out: str | Path | None = None,
    width: int = 640,
    height: int = 480,
    env_kwargs: dict[str, Any] | None = None,
    frames_png: str | Path | None = None,
    progress_bar: bool = True,
    camera_distance: float = FILM_CAMERA_DISTANCE,
    policy_captions: bool = False,
) -> dict[str, Any]:
    """Render ``policy`` in ``env_id`` to the MP4 ``out``: one episode to its end (``seconds`` None;
    at most :data:`MAX_EPISODE_SECONDS`, then its last frame held :data:`OUTCOME_HOLD_SECONDS` with
    the outcome written on it) or ``seconds`` of video (episodes restarted). Returns a summary dict
    (``path``, ``frames``, ``fps``, ``steps``, ``episodes``, ``best_progress`` (None unless the env
    reports InterLevel's ``progress``), ``successes``, ``falls``, ``unstable``, ``outcome`` (how the
    last episode filmed ended, :func:`outcome_of`), ``pngs``, ``policy``: the spec loaded,
    ``note``: :func:`resolve_policy`'s, ``captions``: the policy's captions drawn, else None). ``policy``
    None or "pretrained" is resolved by :func:`resolve_policy`. ``policy_captions``: a text-conditioned
    env draws the captions the policy recorded from its training (``stairenv.pretrained.trained_captions``;
    the env's own where it recorded none or ``env_kwargs`` name some). Raises ``ValueError`` for bad arguments."""
    import gymnasium as gym
    import imageio.v2 as imageio
    import numpy as np
    from tqdm.auto import tqdm

    import stairenv  # noqa: F401  (registers the envs, picks EGL without a display)
    from stairenv.policy_loading import load_policy
    from stairenv.pretrained import with_trained_captions

    if seconds is not None and not (isinstance(seconds, (int, float)) and np.isfinite(seconds)
                                    and 0 < seconds <= 600):
        raise ValueError(f"seconds must be None (one episode) or in (0, 600], got {seconds!r}")
    if seed < 0:
        raise ValueError(f"seed must be >= 0, got {seed!r}")
    for name, value in (("width", width), ("height", height)):
        if not 16 <= value <= 4096:
            raise ValueError(f"{name} must be in [16, 4096] pixels, got {value!r}")
    if not (isinstance(camera_distance, (int, float)) and 0.5 <= camera_distance <= 50):
        raise ValueError(f"camera_distance must be in [0.5, 50] m, got {camera_distance!r}")
    check_env_id(env_id)
    taken = sorted(set(env_kwargs or {}) & set(FILM_KEYWORDS))
    if taken:
        raise ValueError(f"env keyword(s) {taken}: the film sets them itself (use --width and --height)")
    out = Path(default_out(env_id) if out is None else out)
    if out.suffix.lower() != ".mp4":
        raise ValueError(f"out must be an .mp4 path, got {str(out)!r}")
    # the outputs are checked before the film is made (it used to fail at its end, in ffmpeg)
    out = check_output("--out", out)
    png_dir = None if frames_png is None else check_output("--frames-png", frames_png, folder=True)

    policy, note = resolve_policy(policy, env_id)
    env = gym.make(env_id, render_mode="rgb_array", width=width, height=height, **(env_kwargs or {}))
    try:
        act = load_policy(policy, env, seed=seed)
        captions, given = None, dict(env_kwargs or {})
        filmed_kwargs = with_trained_captions(given, act) if policy_captions else given
        if filmed_kwargs is not given:
            env.close()
            env = gym.make(env_id, render_mode="rgb_array", width=width, height=height, **filmed_kwargs)
            captions = filmed_kwargs["captions"]
        fps = int(env.metadata["render_fps"])
        one_episode = seconds is None
        n_frames = max(1, int(round((MAX_EPISODE_SECONDS if one_episode else seconds) * fps)))
        policy_name = Path(policy).name if Path(policy).suffix else policy

        # best_progress: InterLevel's stair progress; None for envs that report none (PlaMo, SIMS)
        stats = {"steps": 0, "episodes": 1, "best_progress": None, "successes": 0, "falls": 0, "unstable": 0,
                 "outcome": "still running"}
        episode_progress: dict[str, float] = {}    # the filmed episode's best, which its frames show
        pngs: list[str] = []
        episode_seed = seed
        episode_step = 0

        def reset() -> np.ndarray:
            if callable(getattr(act, "reset", None)):
                act.reset(episode_seed)
            obs, info = env.reset(seed=episode_seed)
            env.unwrapped.set_camera(FILM_CAMERA_ELEVATION, camera_distance)
            episode_progress.clear()
            note_progress(info)
            note_task(info)
            return obs

        def note_progress(info: dict) -> None:
            if "progress" in info and not info.get("physics_unstable", False):
                stats["best_progress"] = max(stats["best_progress"] or 0.0, float(info["progress"]))
                episode_progress["best"] = max(episode_progress.get("best", 0.0), float(info["progress"]))

        def labelled(frame: np.ndarray, banner: str | None = None) -> np.ndarray:
            lines = [f"{env_id}  |  {policy_name}", f"episode {stats['episodes']}  t = {episode_step / fps:4.1f} s"]
            if "best" in episode_progress:
                lines[-1] += f"  |  progress {100 * episode_progress['best']:.0f}%"
            task = task_text.get("text")    # PlaMoScene's instructions, a SIMS caption
            if task:
                lines.append(f'"{task}"')
            return caption_frame(frame, lines, banner)

        task_text: dict[str, str] = {}

        def note_task(info: dict) -> None:
            text = info.get("instructions") or info.get("caption")
            if isinstance(text, str):
                task_text["text"] = text

        obs = reset()
        written = 0
        with written_whole(out) as partial:  # moved to ``out`` once whole; removed if the film stops
            made_png_folders = _make_folders(png_dir) if png_dir is not None else []
            try:
                # libx264 needs even frame sizes; macro_block_size=2 rounds odd ones up without a warning.
                writer = imageio.get_writer(partial, fps=fps, codec="libx264", quality=7, macro_block_size=2,
                                            pixelformat="yuv420p")
                try:
                    for k in tqdm(range(n_frames), desc=f"rendering {out.name}", unit="frame",
                                  disable=not progress_bar):
                        ended = False
                        if k > 0:
                            obs, _, terminated, truncated, info = env.step(np.asarray(act(obs)))
                            stats["steps"] += 1
                            episode_step += 1
                            note_progress(info)
                            note_task(info)
                            stats["outcome"] = outcome_of(info, terminated, truncated)
                            if terminated or truncated:
                                ended = True
                                stats["successes"] += bool(info.get("success"))
                                stats["falls"] += bool(info.get("fell"))
                                stats["unstable"] += bool(info.get("physics_unstable"))
                        frame = labelled(env.render())
                        writer.append_data(frame)
                        written += 1
                        if png_dir is not None and k % fps == 0:
                            path = png_dir / f"frame_{k // fps:03d}s.png"
                            imageio.imwrite(path, frame)
                            pngs.append(str(path))
                        if one_episode and (ended or k == n_frames - 1):
                            break
                        if ended and k < n_frames - 1:
                            episode_seed += 1
                            stats["episodes"] += 1
                            episode_step = 0
                            obs = reset()
                    if one_episode:  # the outcome, written on the last frame, held
                        banner = stats["outcome"] if stats["outcome"] != "still running" else (
                            f"stopped after {MAX_EPISODE_SECONDS:.0f} s")
                        last = labelled(env.render(), banner.upper())
                        for _ in range(max(1, int(round(OUTCOME_HOLD_SECONDS * fps)))):
                            writer.append_data(last)
                            written += 1
                finally:
                    writer.close()
            except BaseException:  # no stills of a film that is not written
                for png in pngs:
                    with contextlib.suppress(OSError):
                        Path(png).unlink()
                pngs.clear()
                _remove_folders(made_png_folders)
                raise
    finally:
        env.close()
    return {"path": str(out), "frames": written, "fps": fps, "pngs": pngs, "policy": policy, "note": note,
            "captions": captions, **stats}


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``python -m stairenv`` and the ``stairenv`` console script."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        check_env_id(args.env)    # before a policy is looked up for it
        policy, note = resolve_policy(args.policy, args.env)
        if note:
            print(note, flush=True)
        summary = record(
            env_id=args.env,
            policy=policy,
            seconds=args.seconds,
            seed=DEFAULT_SEEDS.get(args.env, 0) if args.seed is None else args.seed,
            out=args.out,
            width=args.width,
            height=args.height,
            env_kwargs=dict(args.env_kwarg),
            frames_png=args.frames_png,
            progress_bar=not args.no_progress,
            camera_distance=args.camera_distance,
            policy_captions=args.policy_captions,
        )
    except (ValueError, TypeError) as error:    # TypeError: an env keyword of the wrong type, which it names
        parser.error(str(error))
    print(f"wrote {summary['path']} ({summary['frames']} frames, {summary['frames'] / summary['fps']:.1f} s at {summary['fps']} fps)")
    if summary["pngs"]:
        print(f"wrote {len(summary['pngs'])} PNG stills to {Path(summary['pngs'][0]).parent}")
    label = args.policy or (FALLBACK_POLICY if policy == FALLBACK_POLICY else PRETRAINED)
    progress = "" if summary["best_progress"] is None else f"best progress {100 * summary['best_progress']:.1f}%, "
    print(
        f"{label} on {args.env}: {summary['steps']} steps, {summary['episodes']} episode(s), "
        f"{progress}{summary['successes']} success(es), "
        f"{summary['falls']} fall(s)" + (f", {summary['unstable']} unstable" if summary["unstable"] else "")
        + (f"; the episode filmed: {summary['outcome']}" if args.seconds is None else "")
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
