import os

# Offscreen rendering in tests (must be set before mujoco is imported).
os.environ.setdefault("MUJOCO_GL", "egl")

import pytest  # noqa: E402


@pytest.fixture(autouse=True, scope="session")
def _sb3_logs_in_a_temporary_folder(tmp_path_factory):
    """SB3 makes an empty SB3-<date> folder in the system temp dir for every ``learn`` without
    TensorBoard; keep them inside pytest's own temporary folders (subprocesses inherit it)."""
    yield from _environ("SB3_LOGDIR", tmp_path_factory.mktemp("sb3-logs"))


@pytest.fixture(autouse=True, scope="session")
def _a_cache_of_this_session(tmp_path_factory):
    """The package's cache (``$STAIRENV_CACHE``: text embeddings, stair climbs) of this test session alone,
    subprocesses included: what a test synthesises or reads does not depend on what the machine kept before."""
    yield from _environ("STAIRENV_CACHE", tmp_path_factory.mktemp("stairenv-cache"))


def _environ(name: str, value) -> object:
    """A session fixture's body: ``os.environ[name]`` is ``value`` until the session ends, then what it was."""
    previous = os.environ.get(name)
    os.environ[name] = str(value)
    yield
    if previous is None:
        os.environ.pop(name, None)
    else:
        os.environ[name] = previous


@pytest.fixture(scope="session")
def baseline_script():
    """Load ``baselines/<name>.py`` as a module (the scripts are not a package)."""
    import importlib.util
    from pathlib import Path

    folder = Path(__file__).resolve().parents[1] / "baselines"

    def load(name: str):
        spec = importlib.util.spec_from_file_location(f"baseline_{name}", folder / f"{name}.py")
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        return module

    return load


class InProcessScript:
    """A script of ``baselines/`` run in the test's process: ``run(args, cwd)`` returns what it printed,
    ``fails(args, cwd)`` what a run that must stop said (its ``SystemExit`` message and standard error).
    The script's start-up (~5 s of imports, ~2 s of torch's first optimiser, the reference motions read)
    is paid once per test session instead of once a run; each script keeps one test that runs it as a
    script, in its own process."""

    def __init__(self, module, monkeypatch, capsys) -> None:
        self.module, self.monkeypatch, self.capsys = module, monkeypatch, capsys

    def _main(self, args: list[str], cwd) -> None:
        import torch
        threads = torch.get_num_threads()
        self.monkeypatch.chdir(cwd)
        try:
            self.module.main(args)
        finally:
            torch.set_num_threads(threads)    # a trainer's torch_threads: not for the tests after it

    def run(self, args: list[str], cwd) -> str:
        self._main(args, cwd)
        return self.capsys.readouterr().out

    def fails(self, args: list[str], cwd) -> str:
        with pytest.raises(SystemExit) as stop:
            self._main(args, cwd)
        assert stop.value.code not in (None, 0), "the run was to stop with an error"
        return f"{stop.value.code}\n{self.capsys.readouterr().err}"


@pytest.fixture
def train_ppo(baseline_script, monkeypatch, capsys) -> InProcessScript:
    """``baselines/train_ppo.py`` in this process (``InProcessScript``)."""
    return InProcessScript(baseline_script("train_ppo"), monkeypatch, capsys)


@pytest.fixture
def train_sb3(baseline_script, monkeypatch, capsys) -> InProcessScript:
    """``baselines/train_sb3.py`` in this process (``InProcessScript``)."""
    return InProcessScript(baseline_script("train_sb3"), monkeypatch, capsys)
