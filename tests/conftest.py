import os
from pathlib import Path

# One on-disk compilation cache for the whole run (diracvi's own, pointed away from the
# user's cache directory), shared by the xdist workers and the CLI subprocesses: set
# before diracvi is imported, which is when the cache is configured, so they all inherit
# it. Tests rebuild the same problems again and again, and a rebuilt model compiles to
# the same program, which is then loaded, not compiled (3.7 s → 1.0 s CPU for the torn
# RLC's second build). Keyed by the program text, so results are unchanged. The
# controller removes it at the end (pytest_unconfigure below).
if "DIRACVI_CACHE_DIR" not in os.environ:
    _run = os.environ.get("PYTEST_XDIST_TESTRUNUID") or str(os.getpid())
    os.environ["DIRACVI_CACHE_DIR"] = os.path.join(
        os.environ.get("TMPDIR", "/tmp"), f"diracvi-test-xla-cache-{_run}"
    )

# The marching chunks are compiled without XLA's backend (LLVM) optimization: the same
# programs (HLO) as a user's, compiled in about half the time and run up to 2x slower,
# which suits a suite that compiles hundreds of short runs (diracvi.runtime.compile). Run
# ``DIRACVI_FAST_COMPILE=0 pytest`` to test the default machine code; the benchmarks
# (diracvi bench) measure it.
os.environ.setdefault("DIRACVI_FAST_COMPILE", "1")

# One BLAS thread per process: xdist already runs one worker per core, and OpenBLAS's
# own threads on top of that oversubscribe the cores. Its threads spin while they wait,
# so a small dense solve or SVD then takes milliseconds instead of microseconds (the
# dense-check tests: 33 s with the default threads vs 1.2 s with one, on a loaded
# 2-core machine). Set before NumPy is imported, which is when OpenBLAS reads it.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import numpy as np
import pytest
from hypothesis import HealthCheck, settings

import diracvi as dv

# Hypothesis profiles. "ci" (the default) is derandomized: the same draws on every run, so
# CI is reproducible. "slow" searches for real: random draws, 10× the examples of every test
# (each test's budget is given through examples(n) below). Choose it with
#     pytest --hypothesis-profile=slow        (or HYPOTHESIS_PROFILE=slow)
CI_EXAMPLES = 30
_common = {
    "deadline": None,
    "suppress_health_check": [HealthCheck.too_slow, HealthCheck.data_too_large],
}
settings.register_profile("ci", max_examples=CI_EXAMPLES, derandomize=True, **_common)
settings.register_profile("slow", max_examples=10 * CI_EXAMPLES, derandomize=False, **_common)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))


def examples(n: int) -> settings:
    """``@examples(n)``: n examples under the "ci" profile, scaled with the loaded one.

    Decorators run when the test modules are collected, after ``--hypothesis-profile`` has
    loaded its profile, so ``settings.default`` is the profile of this run.
    """
    scale = settings.default.max_examples / CI_EXAMPLES
    return settings(max_examples=max(1, round(n * scale)))


def run(problem, **overrides):
    """Simulate a built-in problem with its own step and horizon unless overridden."""
    kwargs = {"dt": problem.dt, "steps": problem.steps, "t0": problem.t0, **overrides}
    return dv.simulate(problem.system, problem.q0, problem.p0, **kwargs)


def loglog_slope(hs, errors) -> float:
    """The fitted exponent r of error ≈ C h^r."""
    return float(np.polyfit(np.log(hs), np.log(errors), 1)[0])


@pytest.fixture
def rng():
    return np.random.default_rng(20261121)


SLOW_FOR_TIME = Path(__file__).with_name("slow_for_time.txt")


def slow_for_time() -> set[str]:
    """The default tests moved behind ``slow`` for CI's time (``slow_for_time.txt``)."""
    lines = SLOW_FOR_TIME.read_text(encoding="utf-8").splitlines()
    return {line.split(None, 1)[1].strip() for line in lines if line and line[0] != "#"}


@pytest.hookimpl(tryfirst=True)  # before `-m` deselects by marker
def pytest_collection_modifyitems(session, config, items):
    listed = slow_for_time()
    seen = set()
    for item in items:
        if item.nodeid in listed:
            item.add_marker(pytest.mark.slow)
            seen.add(item.nodeid)
    # a whole-suite collection must find every listed test: a renamed or removed test
    # would otherwise leave a stale line, and its replacement would run by default unseen
    whole = not config.args or [Path(a).resolve() for a in config.args] == [
        Path(config.rootpath, "tests").resolve()
    ]
    stale = sorted(listed - seen)
    if whole and stale and not config.getoption("keyword", ""):
        raise pytest.UsageError(
            f"{SLOW_FOR_TIME.name} names tests that were not collected: {', '.join(stale)}. "
            "Fix: update or remove those lines."
        )


def pytest_unconfigure(config):
    """The run's compilation cache goes with the run (the controller removes it last)."""
    cache = os.environ.get("DIRACVI_CACHE_DIR", "")
    if hasattr(config, "workerinput") or "diracvi-test-xla-cache-" not in cache:
        return
    import shutil

    shutil.rmtree(cache, ignore_errors=True)


def one_rule_each(names, rules=("retraction", "midpoint")):
    """``(name, rule)`` cases where each name runs with one of its rules by default, taking
    turns, and with the others under ``-m slow``: every model and every rule are covered
    by default at a fraction of the compilations (each case compiles its own programs).
    ``rules``: one tuple for all names, or a function ``name -> rules``."""
    cases = []
    for i, name in enumerate(names):
        own = tuple(rules(name) if callable(rules) else rules)
        for j, rule in enumerate(own):
            slow = j != i % len(own)
            cases.append(pytest.param(name, rule, marks=[pytest.mark.slow] if slow else []))
    return cases


# ---------------------------------------------------------------- what the run left out
# A default run deselects the slow and docs tests (pyproject's addopts); the summary says
# how many and how to run them, also under pytest-xdist, whose controller collects nothing:
# each worker reports its counts (all workers collect, and deselect, the same tests).
_DESELECTED: dict[str, int] = {}


def _marker_label(item) -> str:
    marks = [m for m in ("slow", "docs") if item.get_closest_marker(m)]
    return " + ".join(marks) or "unmarked"


def pytest_deselected(items):
    for item in items:
        label = _marker_label(item)
        _DESELECTED[label] = _DESELECTED.get(label, 0) + 1


def pytest_sessionfinish(session):
    if hasattr(session.config, "workeroutput"):
        session.config.workeroutput["diracvi_deselected"] = dict(_DESELECTED)


@pytest.hookimpl(optionalhook=True)
def pytest_testnodedown(node, error):
    reported = getattr(node, "workeroutput", {}).get("diracvi_deselected")
    if reported and not _DESELECTED:
        _DESELECTED.update(reported)


def pytest_terminal_summary(terminalreporter, config):
    if hasattr(config, "workerinput") or not _DESELECTED:
        return
    total = sum(_DESELECTED.values())
    counts = ", ".join(f"{n} {label}" for label, n in sorted(_DESELECTED.items()))
    rest = ""
    if set(_DESELECTED) - {"unmarked"}:
        rest = (
            f" (-m {config.option.markexpr!r}); run the rest with pytest -m slow, "
            "pytest -m docs (needs the docs extra), or pytest -m 'slow or docs'"
        )
    terminalreporter.write_sep("-", f"not run: {total} deselected tests ({counts}){rest}")
