"""Load a user's model file for ``diracvi run path/to/model.py``.

The contract: the file defines ``build()``, called with no arguments, which returns

- a tuple ``(system, q0, p0)``, or ``(system, q0, p0, {"dt": ..., "steps": ...})``
  (the dict may hold either key or both), or
- a mapping with keys ``"system"``, ``"q0"``, ``"p0"`` and optionally ``"dt"``,
  ``"steps"``, or
- any object with those attributes (a :class:`diracvi.problems.Problem` qualifies).

``dt`` and ``steps``, when given, are the defaults for ``--dt`` and ``--steps``.
"""

from __future__ import annotations

import importlib.util
import sys
import traceback
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from ..errors import ModelError
from .system import DiracSystem


@dataclass(frozen=True)
class ModelSpec:
    """What a model file provides."""

    name: str
    system: DiracSystem
    q0: object
    p0: object
    dt: float | None = None
    steps: int | None = None
    discretizations: tuple[str, ...] = ("retraction", "midpoint")


def _where(exc: BaseException, path: Path) -> str:
    """``" (model.py, line 12)"`` for the deepest frame of the traceback inside ``path``."""
    frames = [f for f in traceback.extract_tb(exc.__traceback__) if Path(f.filename) == path]
    return f" ({path.name}, line {frames[-1].lineno})" if frames else ""


def load_model_file(path) -> ModelSpec:
    """Import ``path`` and call its ``build()``; raise :class:`ModelError` on any problem."""
    path = Path(path).resolve()
    build = load_build(path)
    try:
        built = build()
    except Exception as exc:
        if isinstance(exc, ModelError):
            raise
        raise ModelError(
            f"build() in {str(path)!r} raised {type(exc).__name__}: {exc}{_where(exc, path)}"
        ) from exc
    return _to_spec(built, path)


def load_build(path):
    """Import the model file ``path`` and return its ``build`` function (not called)."""
    path = Path(path).resolve()
    name = f"diracvi_model_{path.stem}"
    spec = importlib.util.spec_from_file_location(name, path)
    if spec is None or spec.loader is None:
        raise ModelError(f"model file {str(path)!r} cannot be imported as Python.")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # dataclasses and pickling look modules up by name
    try:
        spec.loader.exec_module(module)
    except Exception as exc:
        raise ModelError(
            f"model file {str(path)!r} raised {type(exc).__name__}: {exc}{_where(exc, path)} "
            "while being imported."
        ) from exc
    build = getattr(module, "build", None)
    if not callable(build):
        raise ModelError(
            f"model file {str(path)!r} defines no build() function: add "
            "def build(): return system, q0, p0 (or a dict with system, q0, p0, dt, steps)."
        )
    return build


def _to_spec(built, path: Path) -> ModelSpec:
    fields = {}
    if isinstance(built, tuple | list) and len(built) == 3:
        fields = dict(zip(("system", "q0", "p0"), built, strict=True))
    elif isinstance(built, tuple | list) and len(built) == 4 and isinstance(built[3], Mapping):
        fields = {**dict(built[3]), **dict(zip(("system", "q0", "p0"), built[:3], strict=True))}
    elif isinstance(built, Mapping):
        fields = dict(built)
    elif all(hasattr(built, k) for k in ("system", "q0", "p0")):
        fields = {
            k: getattr(built, k) for k in ("system", "q0", "p0", "dt", "steps") if hasattr(built, k)
        }
        if hasattr(built, "discretizations"):
            fields["discretizations"] = tuple(built.discretizations)
    missing = [k for k in ("system", "q0", "p0") if k not in fields]
    if missing:
        raise ModelError(
            f"build() in {str(path)!r} returned {type(built).__name__}, which lacks "
            f"{missing}: return (system, q0, p0), (system, q0, p0, {{'dt': ..., 'steps': ...}}), "
            "or a dict/object with system, q0, p0 (and optionally dt, steps)."
        )
    if not isinstance(fields["system"], DiracSystem):
        raise ModelError(
            f"build() in {str(path)!r} returned system={fields['system']!r}, which is not a "
            "diracvi system: build it with dv.LagrangeDiracSystem(...) or dv.interconnect(...)."
        )
    unknown = sorted(set(fields) - {"system", "q0", "p0", "dt", "steps", "discretizations"})
    if unknown:
        raise ModelError(
            f"build() in {str(path)!r} returned unknown keys {unknown}; the allowed keys "
            "are system, q0, p0, dt, steps."
        )
    return ModelSpec(
        name=path.stem,
        system=fields["system"],
        q0=fields["q0"],
        p0=fields["p0"],
        dt=fields.get("dt"),
        steps=fields.get("steps"),
        discretizations=fields.get("discretizations", ("retraction", "midpoint")),
    )


_SOURCES: dict = {}


class ModelFileBuild:
    """A model file's ``build`` that can be sent to other processes (Dask workers).

    It carries the file's source text rather than the function, and imports it on first
    use in each process (as module ``diracvi_model_<stem>``): classes defined in the
    file — ``equinox.Module`` parameters in particular — cannot be pickled by value, and
    the workers of a cluster need not see the file.
    """

    def __init__(self, path):
        self.path = Path(path).resolve()
        self.source = self.path.read_text(encoding="utf-8")
        self.__module__ = f"diracvi_model_{self.path.stem}"
        self.__qualname__ = "build"
        self.build()  # import errors and a missing build() are reported here

    def build(self):
        key = (str(self.path), self.source)
        if key not in _SOURCES:
            name = f"diracvi_model_{self.path.stem}"
            module = type(sys)(name)
            module.__file__ = str(self.path)
            sys.modules[name] = module
            try:
                exec(compile(self.source, str(self.path), "exec"), module.__dict__)
            except Exception as exc:
                raise ModelError(
                    f"model file {str(self.path)!r} raised {type(exc).__name__}: {exc}"
                    f"{_where(exc, self.path)} while being imported."
                ) from exc
            build = getattr(module, "build", None)
            if not callable(build):
                raise ModelError(
                    f"model file {str(self.path)!r} defines no build() function: add "
                    "def build(**values): return system, q0, p0."
                )
            _SOURCES[key] = build
        return _SOURCES[key]

    @property
    def __signature__(self):
        import inspect

        return inspect.signature(self.build())

    def __call__(self, **values):
        return self.build()(**values)

    def __getstate__(self):
        return {"path": self.path, "source": self.source}

    def __setstate__(self, state):
        self.path, self.source = state["path"], state["source"]
        self.__module__ = f"diracvi_model_{self.path.stem}"
        self.__qualname__ = "build"
