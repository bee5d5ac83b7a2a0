import os

# Offscreen rendering in tests (must be set before mujoco is imported).
os.environ.setdefault("MUJOCO_GL", "egl")

import pytest  # noqa: E402


@pytest.fixture(autouse=True, scope="session")
def _sb3_logs_in_a_temporary_folder(tmp_path_factory):
    """SB3 makes an empty SB3-<date> folder in the system temp dir for every ``learn`` without
    TensorBoard; keep them inside pytest's own temporary folders (subprocesses inherit it)."""
    folder = tmp_path_factory.mktemp("sb3-logs")
    previous = os.environ.get("SB3_LOGDIR")
    os.environ["SB3_LOGDIR"] = str(folder)
    yield
    if previous is None:
        os.environ.pop("SB3_LOGDIR", None)
    else:
        os.environ["SB3_LOGDIR"] = previous


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
