"""Fuzzing model files given to ``diracvi run``: whatever the file holds, the command ends
with exit code 0, 1 or 2 and a message — never a traceback, a crash or a hang."""

from __future__ import annotations

import itertools

from hypothesis import given
from hypothesis import strategies as st
from typer.testing import CliRunner

from conftest import examples
from diracvi.cli import app

runner = CliRunner()
COUNTER = itertools.count()

PREAMBLES = [
    "import diracvi as dv\nimport jax.numpy as jnp\n",
    "import diracvi as dv\n",
    "import no_such_package\n",
    "this is not python (\n",
    "",
]
LAGRANGIANS = [
    "lambda q, v: 0.5 * v @ v - 0.5 * q @ q",
    "lambda q, v: v",
    "lambda q, v: 0.5 * v[0] ** 2",  # degenerate in the second coordinate
    "lambda q, v: jnp.sqrt(1.0 - q[0]) + 0.5 * v @ v",  # NaN past q = 1
    "None",
    "lambda q: q",
]
STATES = ["[0.0, 0.5]", "[0.0]", "[float('nan'), 0.0]", "'abc'", "[[0.0, 1.0]]", "[0.0, 3.0]"]
RETURNS = [
    "system, {q0}, {p0}",
    "{{'system': system, 'q0': {q0}, 'p0': {p0}, 'dt': 0.05, 'steps': 40}}",
    "{{'system': system, 'q0': {q0}}}",
    "system",
    "None",
    "1 / 0",
]


@examples(30)
@given(
    preamble=st.sampled_from(PREAMBLES),
    lagrangian=st.sampled_from(LAGRANGIANS),
    q0=st.sampled_from(STATES),
    p0=st.sampled_from(STATES),
    returned=st.sampled_from(RETURNS),
    has_build=st.booleans(),
)
def test_any_model_file_ends_in_a_clean_exit(
    tmp_path_factory, preamble, lagrangian, q0, p0, returned, has_build
):
    body = preamble
    if has_build:
        body += (
            "\ndef build():\n"
            f"    system = dv.LagrangeDiracSystem(('x', 'y'), {lagrangian}, name='m')\n"
            f"    return {returned.format(q0=q0, p0=p0)}\n"
        )
    path = tmp_path_factory.mktemp("models") / f"model_{next(COUNTER)}.py"
    path.write_text(body)
    result = runner.invoke(app, ["run", str(path), "--dt", "0.05", "--steps", "40"])
    assert result.exit_code in (0, 1, 2), result.output
    assert "Traceback" not in result.output
    assert not isinstance(result.exception, Exception) or isinstance(
        result.exception, SystemExit
    ), repr(result.exception)
    if result.exit_code:
        assert result.output.strip()  # a message, not silence
