"""Train PPO + AMP (Stable-Baselines3) on a stairenv env with the InterLevel paper's settings.

    python baselines/train_ppo.py                         # InterLevel-v0, PPO + AMP, paper settings
    python baselines/train_ppo.py --env InterLevel2D-v0   # the 2-D ablation
    python baselines/train_ppo.py --env InterSceneStairs-v0 --style none   # task reward only
    python baselines/train_ppo.py --env-kwarg target_speed=0.8 --timesteps 5e6
    python baselines/train_ppo.py --config my_run.toml    # any of the flags below as keys
    python baselines/train_ppo.py --resume runs/InterLevel-v0/seed0/checkpoints/ppo_100000_steps.zip
    python baselines/train_ppo.py --resume .../ppo_100000_steps.zip --fresh-discriminator   # AMP state lost
    python baselines/train_ppo.py --preset style-short    # instance noise + stable PPO for short runs (below)
    python baselines/train_ppo.py --env SIMS-Sit-v0 --amp-text-condition   # SIMS: discriminator sees the caption

``--amp-text-condition`` (SIMS envs with ``text_conditioned``): the discriminator
judges [motion window, text embedding]; each reference clip is embedded from its
``meta["text"]`` with the env's encoder, and the env's captions become the
reference texts of its skill, so agent and reference conditions come from one set.

Paper settings (InterLevel): learning rate 2e-5 constant, MLP
[1024, 512] ReLU for policy and value, gradient-norm clip 1.0, entropy 0,
gamma 0.99, minibatch 64, observation and return normalisation (VecNormalize).
Style: the AMP discriminator wrapper (``stairenv.style.wrappers``) trained on
reference clips (``--reference``; default: the env's built-in synthesised set,
walks and stair ascents, or for SIMS envs walks plus sit / lie / reach / get-up
clips), reward 0.5 task + 0.5 style, episodes started half from
reference states (``--init hybrid``).

``--preset style-short`` (``PRESETS``; flags and ``--config`` keys win over it) is
for short runs on a CPU: instance noise 1.0 on the discriminator's training inputs,
policy learning rate 1e-5 with log std -2, style weighted 0.8 (task 0.2), gradient
penalty 10 and a 200k-window replay buffer. The runs behind each setting are in
``docs/reproducing.md`` ("Why --preset style-short").

Writes to ``--logdir/<env>/seed<k>/``: TensorBoard logs (PPO and ``amp/*``),
checkpoints (model, VecNormalize statistics, AMP state), ``final_model.zip`` +
``vecnormalize.pkl`` + ``amp.pt`` and the evaluation table
(``evaluation.csv`` / ``.json``) of the trained policy, by the evaluator of the env's family
(``stairenv.evaluation.evaluator_for``: InterLevel Tables 1-3, PlaMo Table 2 or SIMS Table 1);
the JSON is a list of reports.

``--resume`` needs the checkpoint's VecNormalize statistics and, with AMP, its
AMP state (``amp_<n>_steps.pt``, or ``amp.pt`` beside ``final_model.zip``); without
the AMP state it stops unless ``--fresh-discriminator`` asks for a new one. The
model .zip and statistics .pkl are pickles (SB3's formats): resume only from files
you trust. The AMP state is read without running code from it.
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
import tomllib
from pathlib import Path

import gymnasium as gym
import torch
from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import BaseCallback, CallbackList, CheckpointCallback
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecMonitor, VecNormalize

import stairenv  # noqa: F401  (registers the envs)
from stairenv.environments.sims import SIMSEnv, reference_captions
from stairenv.evaluation import evaluator_for
from stairenv.evaluation.cli import env_kwarg_argument
from stairenv.evaluation.policies import load_policy, normalizer_beside, read_normalizer
from stairenv.evaluation.report import write_reports
from stairenv.motion.rsi import load_reference_library
from stairenv.style.discriminator import LOSSES, SCORERS, DiscriminatorConfig
from stairenv.style.pipeline import PIPELINE_CHOICES
from stairenv.style.reference import ReferenceWindows, text_conditions
from stairenv.style.wrappers import AMPStateError, AMPStyleReward, AMPVecEnvWrapper
from stairenv.vec_sb3 import make_sb3_vec_env

PAPER_PPO = {
    "learning_rate": 2e-5,
    "n_steps": 256,
    "batch_size": 64,
    "n_epochs": 5,
    "gamma": 0.99,
    "gae_lambda": 0.95,
    "clip_range": 0.2,
    "ent_coef": 0.0,
    "max_grad_norm": 1.0,
}


# Named groups of flag values (see the module docstring); explicit flags and --config keys win.
PRESETS: dict[str, dict] = {
    "paper": {},
    "style-short": {
        "learning_rate": 1e-5,
        "log_std_init": -2.0,
        "w_task": 0.2,
        "w_style": 0.8,
        "disc_grad_penalty": 10.0,
        "disc_replay_size": 200_000,
        "disc_input_noise": 1.0,
    },
}


def _layer_sizes(text: str) -> tuple[int, ...]:
    try:
        sizes = tuple(int(v) for v in str(text).replace(" ", "").strip("[]()").split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected layer sizes like 1024,512, got {text!r}") from None
    if not sizes or min(sizes) < 1:
        raise argparse.ArgumentTypeError(f"expected positive layer sizes like 1024,512, got {text!r}")
    return sizes


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--config", type=Path, help="TOML file whose keys set any flag below (flags win)")
    p.add_argument("--preset", choices=sorted(PRESETS), default="paper",
                   help="named flag values (flags and --config win); style-short: see above")
    p.add_argument("--env", default="InterLevel-v0", help="registered env id")
    p.add_argument("--env-kwarg", action="append", type=env_kwarg_argument, default=[], metavar="KEY=VALUE")
    p.add_argument("--timesteps", type=float, default=2e6)
    p.add_argument("--n-envs", type=int, default=4)
    p.add_argument("--vec-env", choices=("dummy", "subproc", "batched"), default="dummy",
                   help="dummy: the envs step in this process, their style windows scored on the second core while "
                        "the next envs step (see docs/reproducing.md); subproc: a process per env; batched: the "
                        "natively batched env (stairenv.vec_sb3), one step call advancing every world's physics on "
                        "every core")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--logdir", type=Path, default=Path("runs"))
    p.add_argument("--checkpoint-every", type=int, default=100_000, help="env steps between checkpoints")
    p.add_argument("--resume", type=Path, help="checkpoint .zip to continue from")
    p.add_argument("--fresh-discriminator", action="store_true",
                   help="with --resume: train a new discriminator (--disc-* flags) instead of the AMP state "
                        "saved beside the checkpoint")
    p.add_argument("--eval-episodes", type=int, default=50, help="0 skips the final evaluation")
    p.add_argument("--eval-max-episode-steps", type=int, default=None, help="shorter evaluation episodes")
    p.add_argument("--style", choices=("amp", "none"), default="amp", help="add the AMP style reward")
    p.add_argument("--reference", default=None,
                   help="folder or .npz of reference clips, or builtin:stairs / builtin:sims (default: the env's)")
    p.add_argument("--amp-text-condition", action="store_true",
                   help="SIMS: condition the discriminator on the caption's text embedding (see above)")
    p.add_argument("--init", choices=("default", "reference", "hybrid"), default="hybrid",
                   help="episode start: standing, reference frames, or half/half")
    p.add_argument("--w-task", type=float, default=0.5)
    p.add_argument("--w-style", type=float, default=0.5)
    p.add_argument("--amp-history", type=int, default=2, help="frames per discriminator sample")
    p.add_argument("--disc-loss", choices=LOSSES, default="lsgan")
    p.add_argument("--disc-lr", type=float, default=1e-4)
    p.add_argument("--policy-hidden", type=_layer_sizes, default=(1024, 512), metavar="N,N",
                   help="policy and value network hidden layers (paper: 1024,512)")
    p.add_argument("--disc-hidden", type=_layer_sizes, default=(1024, 512), metavar="N,N",
                   help="discriminator hidden layers (paper: 1024,512)")
    p.add_argument("--disc-grad-penalty", type=float, default=5.0, help="gradient penalty weight")
    p.add_argument("--disc-grad-penalty-batch", type=int, default=None,
                   help="reference windows the gradient penalty is estimated on (default: the whole batch)")
    p.add_argument("--disc-weight-decay", type=float, default=1e-4, help="L2 penalty on every discriminator weight")
    p.add_argument("--disc-logit-reg", type=float, default=0.01, help="L2 penalty on the output layer's weights")
    p.add_argument("--disc-input-noise", type=float, default=0.0,
                   help="std of instance noise on the discriminator's normalised training inputs (0: none)")
    p.add_argument("--disc-batch-size", type=int, default=256, help="reference and agent windows per minibatch")
    p.add_argument("--disc-replay-size", type=int, default=100_000, help="agent windows kept for training")
    p.add_argument("--disc-update-interval", type=int, default=2048, help="transitions between training rounds")
    p.add_argument("--disc-updates", type=int, default=2, help="discriminator minibatches per training round")
    p.add_argument("--disc-background", action=argparse.BooleanOptionalAction, default=True,
                   help="train the discriminator in a worker thread while the envs step (rewards lag one round; "
                        "--no-disc-background: in the step that completes a round)")
    p.add_argument("--disc-scoring", choices=SCORERS, default="auto",
                   help="how the discriminator scores each step (numba-parallel: over all cores; bf16: bfloat16)")
    p.add_argument("--disc-pipeline", choices=PIPELINE_CHOICES, default="auto",
                   help="score each env's window on a second core while the next envs step (needs --vec-env dummy; "
                        "auto: where available)")
    p.add_argument("--log-std-init", type=float, default=0.0,
                   help="initial log std of the Gaussian policy (SB3 default 0: std 1 on actions in [-1, 1])")
    p.add_argument("--torch-threads", type=int, default=None, help="torch intra-op threads (default: torch's)")
    p.add_argument("--device", default="cpu")
    p.add_argument("--no-progress-bar", action="store_true")
    for key, value in PAPER_PPO.items():
        p.add_argument(f"--{key.replace('_', '-')}", type=type(value), default=value)
    return p


def _explicit(argv: list[str] | None) -> set[str]:
    """The flags given on the command line (even when equal to their defaults)."""
    probe = build_parser()
    for action in probe._actions:
        action.default = argparse.SUPPRESS
    return set(vars(probe.parse_args(argv)))


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    """Flags, then ``--config`` keys, then ``--preset`` values: the first that sets a key wins."""
    parser = build_parser()
    args = parser.parse_args(argv)
    fixed = _explicit(argv)
    if args.config is not None:
        with args.config.open("rb") as f:
            config = tomllib.load(f)
        known = {a.dest for a in parser._actions}
        unknown = set(config) - known - {"env_kwargs"}
        if unknown:
            raise SystemExit(f"--config {args.config}: unknown keys {sorted(unknown)}; valid: {sorted(known)}")
        for key, value in config.items():
            if key == "env_kwargs":
                args.env_kwarg = list(value.items()) + args.env_kwarg
            elif key not in fixed:
                setattr(args, key, value)
                fixed.add(key)
    for key, value in PRESETS[args.preset].items():
        if key not in fixed:
            setattr(args, key, value)
    if args.env not in gym.registry:
        raise SystemExit(f"--env {args.env!r} is not registered; known stairenv ids: {list(stairenv.ENV_IDS)}")
    if args.n_envs < 1:
        raise SystemExit("--n-envs must be >= 1")
    if args.fresh_discriminator and (args.resume is None or args.style != "amp"):
        raise SystemExit("--fresh-discriminator only applies to --resume with --style amp")
    return args


class AMPCallback(BaseCallback):
    """Logs the discriminator's statistics and saves the AMP state next to each checkpoint."""

    def __init__(self, style: AMPStyleReward, save_freq: int, folder: Path) -> None:
        super().__init__()
        self.style, self.save_freq, self.folder = style, save_freq, folder

    def _on_step(self) -> bool:
        infos = self.locals.get("infos", [])
        if infos:
            self.logger.record_mean("amp/style_reward", float(sum(i["style_reward"] for i in infos) / len(infos)))
            self.logger.record_mean("amp/task_reward", float(sum(i["task_reward"] for i in infos) / len(infos)))
        for key, value in self.style.last_stats.items():
            self.logger.record(f"amp/{key}", value)
        if self.n_calls % self.save_freq == 0:
            self.style.save(self.folder / f"amp_{self.num_timesteps}_steps.pt")
        return True


def _amp_state_candidates(checkpoint: Path) -> list[Path]:
    """Where the AMP state saved with a checkpoint lies (ppo_<n>_steps.zip -> amp_<n>_steps.pt, or amp.pt)."""
    own = [checkpoint.with_name("amp_" + checkpoint.stem.removeprefix("ppo_") + ".pt")]
    return (own if checkpoint.stem.startswith("ppo_") else []) + [checkpoint.parent / "amp.pt"]


def _amp_state_beside(checkpoint: Path) -> Path | None:
    return next((path for path in _amp_state_candidates(checkpoint) if path.is_file()), None)


def _checkpoint_file(resume: Path) -> Path:
    """The --resume checkpoint as an existing file (SB3 also takes it without its .zip)."""
    for candidate in (resume, resume.with_name(resume.name + ".zip")):
        if candidate.is_file():
            return candidate
    raise SystemExit(f"--resume {resume}: no such checkpoint file; give a run's checkpoints/ppo_<n>_steps.zip "
                     "or its final_model.zip")


def _statistics_beside(checkpoint: Path) -> Path:
    stats = normalizer_beside(checkpoint)
    if stats is None:
        raise SystemExit(f"--resume {checkpoint}: no VecNormalize statistics beside it "
                         "(ppo_vecnormalize_<n>_steps.pkl or vecnormalize.pkl); the policy cannot go on without "
                         "the observation normalisation it learnt with: copy the file back or resume from "
                         "another checkpoint")
    return stats


def _required_amp_state(checkpoint: Path) -> Path:
    """The AMP state beside the checkpoint; missing, resuming would silently restart the discriminator."""
    found = _amp_state_beside(checkpoint)
    if found is None:
        expected = " or ".join(str(path) for path in _amp_state_candidates(checkpoint))
        raise SystemExit(f"--resume {checkpoint}: no AMP state beside it ({expected}), so the discriminator "
                         "trained with it is lost: copy it back, or pass --fresh-discriminator to go on "
                         "with a new discriminator (its style rewards start over), or --style none")
    return found


def _run_env(checkpoint: Path) -> str | None:
    """The env id of the run folder a checkpoint lies in (<logdir>/<env>/seed<k>/[checkpoints/])."""
    return next((folder.name for folder in list(checkpoint.parents)[:3] if folder.name in gym.registry), None)


def _check_same_spaces(checkpoint: Path, stats: Path, normalizer: VecNormalize, venv, env_id: str) -> None:
    """Stop when the checkpoint's env (its statistics' spaces) is not --env's."""
    saved = (normalizer.observation_space.shape, normalizer.action_space.shape)
    now = (venv.observation_space.shape, venv.action_space.shape)
    if saved != now:
        origin = _run_env(checkpoint)
        hint = f" (its run folder is {origin}'s)" if origin and origin != env_id else ""
        raise SystemExit(f"--resume {checkpoint}: trained on observations of shape {saved[0]} and actions of shape "
                         f"{saved[1]} (statistics {stats}){hint}, but --env {env_id} gives {now[0]} and {now[1]}: "
                         "pass the --env and --env-kwarg it was trained with")


def _resumed_style(amp_state: Path, reference: ReferenceWindows, seed: int) -> AMPStyleReward:
    try:
        return AMPStyleReward.load(amp_state, reference, seed=seed)
    except (AMPStateError, ValueError) as err:
        raise SystemExit(f"--resume: {err}. To go on with a new discriminator instead, pass --fresh-discriminator"
                         ) from None


def _load_checkpoint(checkpoint: Path, venv, device: str, tensorboard: str | None) -> PPO:
    try:
        return PPO.load(checkpoint, env=venv, device=device, tensorboard_log=tensorboard)
    except Exception as err:  # noqa: BLE001  (a truncated .zip, another algorithm's, other spaces: many types)
        raise SystemExit(f"--resume {checkpoint}: cannot load it as a PPO checkpoint for this env "
                         f"({type(err).__name__}: {err})") from None


def discriminator_config(args: argparse.Namespace) -> DiscriminatorConfig:
    return DiscriminatorConfig(
        hidden=tuple(args.disc_hidden), loss=args.disc_loss, learning_rate=args.disc_lr,
        grad_penalty=args.disc_grad_penalty, grad_penalty_batch=args.disc_grad_penalty_batch,
        weight_decay=args.disc_weight_decay, logit_reg=args.disc_logit_reg, input_noise=args.disc_input_noise,
        batch_size=args.disc_batch_size, replay_size=args.disc_replay_size,
    )


def main(argv: list[str] | None = None) -> Path:
    args = parse_args(argv)
    if args.torch_threads is not None:
        torch.set_num_threads(args.torch_threads)
    env_kwargs = dict(args.env_kwarg)
    env_kwargs.setdefault("init", args.init)
    if args.reference is not None:
        env_kwargs.setdefault("reference_motion", str(args.reference))
    if args.style == "amp":
        env_kwargs.setdefault("amp_history", args.amp_history)
    if args.amp_text_condition and args.style != "amp":
        raise SystemExit("--amp-text-condition needs --style amp")
    checkpoint = stats = amp_state = None
    if args.resume is not None:  # every file first, before minutes of env setup
        checkpoint = _checkpoint_file(args.resume)
        stats = _statistics_beside(checkpoint)
        if args.style == "amp" and not args.fresh_discriminator:
            amp_state = _required_amp_state(checkpoint)
    run_dir = args.logdir / args.env / f"seed{args.seed}"
    run_dir.mkdir(parents=True, exist_ok=True)

    style = None
    reference = None
    if args.style == "amp":
        probe = gym.make(args.env, **env_kwargs).unwrapped
        library = load_reference_library(args.reference if args.reference is not None
                                         else probe.DEFAULT_REFERENCE_MOTION)
        conditions = None
        if args.amp_text_condition:
            if not isinstance(probe, SIMSEnv) or not probe.text_conditioned:
                raise SystemExit(f"--amp-text-condition needs a SIMS env with text_conditioned=True, not {args.env}")
            conditions = text_conditions(library, probe.embed_text)
            env_kwargs.setdefault("captions", reference_captions(library, probe.skill))
        reference = ReferenceWindows(library, num_frames=args.amp_history, fps=1.0 / probe.dt, conditions=conditions)
        probe.close()

    if args.vec_env == "batched":
        # VecMonitor: episode returns and lengths for SB3's rollout/ep_*_mean (make_vec_env's Monitor does it
        # for the other vec envs)
        venv = VecMonitor(make_sb3_vec_env(args.env, n_envs=args.n_envs, seed=args.seed, **env_kwargs))
    else:
        vec_cls = SubprocVecEnv if args.vec_env == "subproc" and args.n_envs > 1 else DummyVecEnv
        venv = make_vec_env(args.env, n_envs=args.n_envs, seed=args.seed, env_kwargs=env_kwargs, vec_env_cls=vec_cls)
    ppo_kwargs = {key: getattr(args, key) for key in PAPER_PPO}
    tensorboard = str(run_dir / "tb") if importlib.util.find_spec("tensorboard") else None

    normalizer = None
    if checkpoint is not None:
        try:
            normalizer = read_normalizer(stats)
        except ValueError as err:
            raise SystemExit(f"--resume {checkpoint}: {err}; copy an intact file back or resume from another "
                             "checkpoint") from None
        _check_same_spaces(checkpoint, stats, normalizer, venv, args.env)

    if reference is not None:
        if amp_state is not None:
            style = _resumed_style(amp_state, reference, args.seed)
        else:
            style = AMPStyleReward(reference, w_task=args.w_task, w_style=args.w_style, seed=args.seed,
                                   update_interval=args.disc_update_interval, updates_per_round=args.disc_updates,
                                   config=discriminator_config(args), background_training=args.disc_background,
                                   scoring=args.disc_scoring)
        venv = AMPVecEnvWrapper(venv, style, pipeline=args.disc_pipeline)

    if normalizer is not None:
        normalizer.set_venv(venv)
        venv = normalizer
        model = _load_checkpoint(checkpoint, venv, args.device, tensorboard)
        discriminator = f", discriminator {amp_state}" if amp_state else ""
        if args.fresh_discriminator:
            discriminator = ", a fresh discriminator (--fresh-discriminator)"
        print(f"resumed from {checkpoint} ({model.num_timesteps} steps) with statistics {stats}{discriminator}")
        origin = _run_env(checkpoint)
        if origin is not None and origin != args.env:
            print(f"note: {checkpoint} comes from a {origin} run; training goes on with --env {args.env}",
                  file=sys.stderr)
    else:
        venv = VecNormalize(venv, norm_obs=True, norm_reward=True, gamma=args.gamma)
        model = PPO(
            "MlpPolicy",
            venv,
            policy_kwargs={"net_arch": {"pi": list(args.policy_hidden), "vf": list(args.policy_hidden)},
                           "activation_fn": torch.nn.ReLU,
                           "log_std_init": args.log_std_init},
            tensorboard_log=tensorboard,
            seed=args.seed,
            device=args.device,
            verbose=0,
            **ppo_kwargs,
        )

    save_freq = max(args.checkpoint_every // args.n_envs, 1)
    callbacks: list[BaseCallback] = [CheckpointCallback(
        save_freq=save_freq, save_path=str(run_dir / "checkpoints"), name_prefix="ppo", save_vecnormalize=True,
    )]
    if style is not None:
        callbacks.append(AMPCallback(style, save_freq, run_dir / "checkpoints"))
    model.learn(
        total_timesteps=int(args.timesteps),
        callback=CallbackList(callbacks),
        progress_bar=not args.no_progress_bar,
        reset_num_timesteps=args.resume is None,
        tb_log_name="ppo",
    )
    model_path = run_dir / "final_model.zip"
    model.save(model_path)
    venv.save(str(run_dir / "vecnormalize.pkl"))
    if style is not None:
        style.save(run_dir / "amp.pt")
    venv.close()
    print(f"saved {model_path}")

    if args.eval_episodes > 0:
        eval_env = gym.make(args.env, **env_kwargs)
        policy = load_policy(str(model_path), eval_env)
        eval_env.close()
        eval_kwargs = {k: v for k, v in env_kwargs.items() if k not in ("init", "reference_motion")}
        evaluate = evaluator_for(args.env)
        report = evaluate(policy, env_id=args.env, episodes=args.eval_episodes, seed=10_000 + args.seed,
                          env_kwargs=eval_kwargs, max_episode_steps=args.eval_max_episode_steps,
                          progress_bar=not args.no_progress_bar, label=str(model_path))
        print(report.format_table())
        write_reports([report], run_dir / "evaluation.csv", run_dir / "evaluation.json")
    return model_path


if __name__ == "__main__":
    main()
