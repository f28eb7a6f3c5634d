r"""XSPICE's memoryless analog code models, ``d_dt``, ``int`` and ``memristor`` on ``A`` lines,
as behavioural sources (``memristor``: a part of its own).

    Aname port… model      .model model KIND(param=value … vector=[v1 v2 …] flag=TRUE)

A code model is a law ``y = f(x₁, …, x_n)`` from its input ports to its output port. Each
port has a type, written ``%type`` before its nodes (else the model's default type):

- inputs ``%v n`` (``x = V(n)``), ``%vd n+ n-`` (``V(n+) − V(n−)``), ``%i n`` and
  ``%id n+ n-`` (the current through a 0 V source that the port puts from ``n+`` to ``n−``
  — ``n`` to ground — so the port shorts its nodes), ``%vnam Vname`` (``i(Vname)``);
- outputs ``%v n`` and ``%vd n+ n-`` (an ideal source ``V(n+) − V(n−) = y``), ``%i n`` and
  ``%id n+ n-`` (the current ``y`` *into* ``n+``, through the model, out of ``n−``: a
  positive ``%i`` output pulls its node down, measured on ngspice 39);
- conductance ports ``%gd n+ n-`` (``%g n``): the input ``x = V(n+) − V(n−)`` and the
  output the current ``y`` from ``n+`` through the model to ``n−`` (a resistor's sense).

A vector port is ``[p₁ p₂ …]``, each element with its own optional ``%type`` (else the one
written before ``[``, else the default); parentheses around a port's nodes are ignored.

Each instance is one :func:`~diracvi.components.BehaviouralSource` — a V-form for a
voltage output, an I-form for a current or conductance output — with the inputs as its
sensed voltages and currents; a ``%i``/``%id`` input adds its 0 V source (a part named
``<instance>#<port>``). So a code model enters the Lagrange–Dirac structure as a B source
does (:mod:`diracvi.components.behavioural`): controls are velocities, the output a force.

The laws (ngspice-39's ``src/xspice/icm/analog`` and ``xtradev``; ``corner`` is the
parabola ``c(x; x₀, y₀, d, s₋, s₊) = y₀ + s₋ (x − x₀) + (s₊ − s₋)(x − x₀ + d)²/(4d)``,
tangent to the line of slope ``s₋`` through ``(x₀, y₀)`` at ``x₀ − d`` and to that of
slope ``s₊`` at ``x₀ + d``):

- ``gain``: ``y = out_offset + gain·(x + in_offset)``.
- ``summer``: ``y = out_gain · Σ_k in_gain_k (x_k + in_offset_k) + out_offset``.
- ``mult``: ``y = out_gain · Π_k in_gain_k (x_k + in_offset_k) + out_offset``.
- ``divide``: ``y = out_offset + out_gain · n / δ(d)`` with ``n = num_gain (x_num +
  num_offset)``, ``d = den_gain (x_den + den_offset)`` and, with ``L = den_lower_limit``
  and ``D = den_domain`` (``·L`` if ``fraction``): ``δ = d`` for ``|d| ≥ L + D``; for
  ``0 ≤ d < L + D``: ``c(d; L, L, D, 0, 1)`` above ``L − D``, else ``L``; for ``−(L + D) <
  d < 0``: ``c(d; −L, −L, D, 0, 1)`` below ``−(L − D)``, else ``−L``. (The negative side
  reuses the positive side's slopes, so ``δ`` jumps by ``D`` at ``d = −L ± D``, as in
  ngspice; ``D`` = 1e-16 by default.)
- ``limit``: ``u = gain (x + in_offset)``, ``d = limit_range`` (``·(U − L)`` if
  ``fraction``), ``L, U = out_lower_limit, out_upper_limit``: ``y = c(u; L, L, d, 0, 1)``
  for ``L − d < u < L + d``, ``L`` below, ``c(u; U, U, d, 1, 0)`` for ``U − d < u < U + d``,
  ``U`` above, ``u`` between (the lower test first, as in ngspice).
- ``climit``: ``limit`` with ``L = x_cntl_lower + lower_delta`` and ``U = x_cntl_upper −
  upper_delta`` inputs; where ``U − L < 2d`` ngspice leaves its output unset, read as 0.
- ``pwl``: the points ``(x_i, y_i)`` joined by lines, extended one segment beyond each end
  (``x_0 = 2x_1 − x_2``; ``y_0`` the same extrapolation, or ``y_1`` if ``limit``), each
  corner ``x_i`` replaced by ``c(x; x_i, y_i, d_i, s_{i−1}, s_i)`` on ``|x − x_i| < d_i``,
  ``d_i = input_domain · min(x_i − x_{i−1}, x_{i+1} − x_i)`` if ``fraction`` (default)
  else ``input_domain``; beyond the end segments' midpoints the end lines continue.
- ``aswitch`` (``cntl_in`` → ``out %gd``): ``y = V_out / r`` with, if ``log`` (default),
  ``r = r_on · exp(ln(r_off/r_on) · (cntl_on − x)/(cntl_on − cntl_off))``, else ``r =
  r_on + (r_off − r_on)(cntl_on − x)/(cntl_on − cntl_off)``; ``r`` clipped to
  ``[r_on, r_off]`` if ``limit`` (default FALSE), else only held above 1 nΩ; ``r_on``
  below 1 mΩ is raised to 1 mΩ.
- ``zener`` (``z %gd``): ngspice's three-region diode (forward exponential, a linear
  middle of slope ``i_sat/10``, a reverse exponential through ``i_breakdown`` at
  ``−v_breakdown``), or its two-segment form when the regions overlap, plus the leakage
  ``(i_rev/v_breakdown)·V`` (:func:`_zener`; ``vt`` = 0.026 V as in ngspice).

- ``d_dt``: ``y = gain · dx/dt + out_offset`` limited as ``limit`` is (``out_lower_limit``,
  ``out_upper_limit`` required, ``limit_range`` absolute). The derivative is the
  behavioural source's (ngspice's ``ddt`` in B sources): a held position ``τ x`` whose
  velocity is ``τ dx/dt``, a state of the structure, not a stored history; ngspice
  differences its input backward (first order) and outputs 0 (not ``out_offset``) at
  ``t = 0``, where diracvi's operating point has ``dx/dt = 0`` and so ``out_offset``.

- ``int`` (``%v``/``%vd`` ports only): ``y = clamp(q)`` with ``q = out_ic + gain ·
  ∫₀ᵗ (x + in_offset) dt`` (``clamp`` as ``limit``'s, ``out_lower_limit``/``out_upper_limit``
  required, ``limit_range`` absolute, default 1e-6). The integral ``q`` is the charge of
  a 1 F capacitor at a hidden node ``<instance>#int`` fed the current ``gain · (x +
  in_offset)`` by an I-form source: a state of the structure, started at ``out_ic`` (the
  operating point holds the node there as it holds a ``.ic`` node; ngspice outputs
  ``out_ic`` at ``t = 0``). ngspice also overwrites its stored integral with the limited
  value at every step (so its state sticks near a limit, ``U − d`` in the small-step
  limit, where this ``q`` runs on): the two agree while ``q`` stays in ``[L + d, U − d]``
  and differ after; a note says so, and ``out_ic`` outside that range is refused.
  The hidden node has no DC path, so :mod:`._gmin` shunts it with ``GMIN`` (noted): the
  integral leaks with time constant ``1 F/GMIN`` = 1e12 s, where ngspice's does not.

- ``memristor`` (``memris %gd`` only): ``i = V/R`` with the state ``dR/dt = f(V)``,
  ``f(V) = β V + ½(α − β)(|V + v_t| − |V − v_t|)``, stopped at ``rmax`` for ``f > 0`` and
  at ``rmin`` for ``f < 0``; ``R = rinit`` at ``t = 0`` (and in ngspice's DC and AC).
  :func:`~diracvi.components.Memristor` on the port (its module says how it enters the
  structure: the port a resistor of value ``R``, the state the voltage of a hidden node
  ``<instance>#r`` that a 1 F capacitor ``<instance>#c`` holds, fed ``f`` by the part, the
  limits two relays whose flips the variable-step driver locates); the operating point
  holds the node at ``rinit`` as it holds a ``.ic`` node. The hidden node gets the GMIN
  shunt (noted), a leak of ``GMIN·R``, 1e-8 Ω/s at 10 kΩ.

Iteration aids that do not change the solution (``pwl``'s input stepping, ``zener``'s
``limit_switch``) are not modelled. Models with other state (``hyst``,
``s_xfer``, …), the digital ones and the hybrid bridges are refused by name.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import jax.numpy as jnp

from .. import components as cp
from ..errors import ModelError
from . import _magnetic
from ._magnetic import _TOKEN, _values

IN = ("v", "vd", "i", "id", "vnam")
OUT = ("v", "vd", "i", "id")
_PAIR = ("vd", "id", "gd", "hd")  # two-node port types


@dataclass(frozen=True)
class Port:
    name: str
    default: str
    allowed: tuple
    vector: bool = False


@dataclass(frozen=True)
class Spec:
    ports: tuple  # the Port list, the output last
    params: dict  # name -> default (None: required; a tuple: a vector's per-element default)
    booleans: tuple = ()
    vectors: tuple = ()  # real vector parameters


_GAIN3 = {"in_offset": 0.0, "gain": 1.0, "out_offset": 0.0}
_ARITH = {"in_offset": (0.0,), "in_gain": (1.0,), "out_gain": 1.0, "out_offset": 0.0}

#: the analog code models read here: ports (output last), parameters and defaults
MODELS = {
    "gain": Spec((Port("in", "v", IN), Port("out", "v", OUT)), _GAIN3),
    "summer": Spec(
        (Port("in", "v", IN, True), Port("out", "v", OUT)), _ARITH, (), ("in_offset", "in_gain")
    ),
    "mult": Spec(
        (Port("in", "v", IN, True), Port("out", "v", OUT)), _ARITH, (), ("in_offset", "in_gain")
    ),
    "divide": Spec(
        (Port("num", "v", IN), Port("den", "v", IN), Port("out", "v", OUT)),
        {
            "num_offset": 0.0,
            "num_gain": 1.0,
            "den_offset": 0.0,
            "den_gain": 1.0,
            "den_lower_limit": 1e-10,
            "den_domain": 1e-16,
            "fraction": False,
            "out_gain": 1.0,
            "out_offset": 0.0,
        },
        ("fraction",),
    ),
    "limit": Spec(
        (Port("in", "v", IN), Port("out", "v", OUT)),
        {
            "in_offset": 0.0,
            "gain": 1.0,
            "out_lower_limit": None,
            "out_upper_limit": None,
            "limit_range": 1e-6,
            "fraction": False,
        },
        ("fraction",),
    ),
    "climit": Spec(
        (
            Port("in", "v", IN),
            Port("cntl_upper", "v", IN),
            Port("cntl_lower", "v", IN),
            Port("out", "v", OUT),
        ),
        {
            "in_offset": 0.0,
            "gain": 1.0,
            "upper_delta": 0.0,
            "lower_delta": 0.0,
            "limit_range": 1e-6,
            "fraction": False,
        },
        ("fraction",),
    ),
    "pwl": Spec(
        (Port("in", "v", IN), Port("out", "v", OUT)),
        {"x_array": None, "y_array": None, "input_domain": 0.01, "fraction": True, "limit": False},
        ("fraction", "limit"),
        ("x_array", "y_array"),
    ),
    "aswitch": Spec(
        (Port("cntl_in", "v", IN), Port("out", "gd", ("gd",))),
        {"cntl_off": 0.0, "cntl_on": 1.0, "log": True, "r_off": 1e12, "r_on": 1.0, "limit": False},
        ("log", "limit"),
    ),
    "d_dt": Spec(
        (Port("in", "v", IN), Port("out", "v", OUT)),
        {
            "out_offset": 0.0,
            "gain": 1.0,
            "out_lower_limit": None,
            "out_upper_limit": None,
            "limit_range": 1e-6,
        },
    ),
    "int": Spec(
        (Port("in", "v", ("v", "vd")), Port("out", "v", ("v", "vd"))),
        {
            "in_offset": 0.0,
            "gain": 1.0,
            "out_lower_limit": None,
            "out_upper_limit": None,
            "limit_range": 1e-6,
            "out_ic": 0.0,
        },
    ),
    "memristor": Spec(
        (Port("memris", "gd", ("gd",)),),
        {"rmin": 10.0, "rmax": 10000.0, "rinit": 7000.0, "alpha": 0.0, "beta": 1.0, "vt": 0.0},
    ),
    "zener": Spec(
        (Port("z", "gd", ("gd",)),),
        {
            "v_breakdown": None,
            "i_breakdown": 2e-2,
            "r_breakdown": 1.0,
            "i_rev": 1e-6,
            "i_sat": 1e-12,
            "n_forward": 1.0,
            "limit_switch": False,
        },
        ("limit_switch",),
    ),
}

#: code models ngspice has that are not built, by what each needs (refused by name)
OTHERS = {
    "a code model with state": ("hyst", "s_xfer", "slew", "oneshot", "delay",
                                "astate", "capacitor", "inductor", "ilimit"),
    "a source": ("sine", "square", "triangle", "file_source", "pwlts", "seegenerator"),
    "a table read from a file": ("table2d", "table3d"),
    "a code model": ("multi_input_pwl", "ota", "cmeter", "lmeter", "potentiometer",
                     "pswitch", "sidiode"),
}  # fmt: skip

READS = (
    "XSPICE's analog code models gain, summer, mult, divide, limit, climit, pwl, d_dt, int, "
    "aswitch, zener and memristor, and the magnetic lcouple and core"
)


def a_line(ctx, name, pos, kw, line):
    """An ``A`` line: a magnetic model (:mod:`._magnetic`) or an analog one (above)."""
    tokens = _TOKEN.findall(line.text)
    if len(tokens) < 3:
        raise line.fail("expected 'Aname port… model' (an XSPICE code model instance)")
    model = ctx.declared(tokens[-1], line, "gain(gain=2)' (or another code model")
    kind = model.kind.lower()
    if kind in _magnetic.PORTS:
        return _magnetic.a_line(ctx, name, pos, kw, line)
    if kind not in MODELS:
        what = next((k for k, names in OTHERS.items() if kind in names), "a code model")
        if kind.startswith(("d_", "adc_", "dac_")):
            what = "a digital model or a bridge"
        raise line.fail(
            f"element {pos[0]!r}: the XSPICE code model {kind!r} (model {model.name!r}, "
            f"{model.where}) is {what} diracvi does not build; diracvi reads {READS}"
        )
    spec = MODELS[kind]
    ports = _ports(tokens[1:-1], spec.ports, line, kind)
    params = _params(model, spec, kind)
    *inputs, (out_type, out_nodes) = ports
    if kind == "int":
        return _int(ctx, name, line, params, inputs[0], out_type, out_nodes, pos[0])
    if kind == "memristor":
        return _memristor(ctx, name, line, params, out_nodes, pos[0])
    return _build(ctx, name, line, kind, spec, params, inputs, out_type, out_nodes, pos[0])


# ------------------------------------------------------------------ the A line's ports
def _ports(tokens, table, line, kind):
    """``[(type, nodes), …]`` per port (a vector port: a list of them)."""
    words = [t for t in tokens if t not in "()"]
    if "~" in words:
        raise line.fail(f"{kind}: '~' (an inverted port) is for digital ports only")
    form = "Aname " + " ".join(
        f"[{p.name}…]" if p.vector else f"[%{'|%'.join(p.allowed)}] {p.name}" for p in table
    ) + " model"  # fmt: skip
    k = 0

    def one(port, default):
        nonlocal k
        kind_of = default
        if k < len(words) and words[k].startswith("%"):
            kind_of = words[k][1:].lower()
            k += 1
        if kind_of not in port.allowed:
            raise line.fail(
                f"{kind} port {port.name!r} takes the types "
                f"{', '.join('%' + a for a in port.allowed)}, not %{kind_of} (form: '{form}')"
            )
        count = 2 if kind_of in _PAIR else 1
        nodes = words[k : k + count]
        if len(nodes) < count or any(n.startswith("%") or n in "[]" for n in nodes):
            raise line.fail(f"{kind} port {port.name!r} (%{kind_of}) needs {count} node(s)")
        k += count
        return kind_of, tuple(nodes)

    out = []
    for port in table:
        if not port.vector:
            out.append(one(port, port.default))
            continue
        default = port.default
        if k < len(words) and words[k].startswith("%"):
            default = words[k][1:].lower()
            k += 1
        if k >= len(words) or words[k] != "[":
            raise line.fail(f"{kind} port {port.name!r} is a vector: write '[n1 n2 …]'")
        k += 1
        items = []
        while k < len(words) and words[k] != "]":
            items.append(one(port, default))
        if k >= len(words):
            raise line.fail(f"{kind} port {port.name!r}: '[' without ']'")
        k += 1
        if len(items) < 2:
            raise line.fail(f"{kind} port {port.name!r} needs two or more inputs, got {items}")
        out.append(items)
    if k != len(words):
        raise line.fail(f"{kind}: {len(words) - k} extra field(s) {words[k:]} (form: '{form}')")
    return out


# ------------------------------------------------------------------- its .model card
def _params(model, spec, kind):
    tokens = _values(model)
    where = f"{kind} model {model.name!r} ({model.where})"
    unknown = sorted(set(tokens) - set(spec.params))
    if unknown:
        raise model.line.fail(
            f"{where}: unknown parameters {unknown} ({kind} has {', '.join(spec.params)}); "
            "remove them"
        )
    out = {"given": set(tokens)}
    for key, default in spec.params.items():
        token = tokens.get(key)
        if token is None:
            if default is None:
                raise model.line.fail(f"{where}: '{key}' is required; add {key}=…")
            out[key] = default
        elif key in spec.booleans:
            word = token.lower()
            if word not in ("t", "true", "f", "false", "0", "1"):
                raise model.line.fail(f"{where}: {key}={token!r} must be TRUE or FALSE")
            out[key] = word in ("t", "true", "1")
        elif key in spec.vectors:
            items = token.strip("[]").replace(",", " ").split()
            out[key] = tuple(model.scope.value(t, model.line, f"{key} entry") for t in items)
        else:
            if token.startswith("["):
                raise model.line.fail(f"{where}: {key} is a number, not a vector {token}")
            out[key] = model.scope.value(token, model.line, f".model {model.name} {key}")
    return out


# ------------------------------------------------------------------------- the part
def _build(ctx, name, line, kind, spec, params, inputs, out_type, out_nodes, written):
    flat = [p for item in inputs for p in (item if isinstance(item, list) else [item])]
    if kind in ("summer", "mult"):
        size = len(inputs[0])
        for key in ("in_offset", "in_gain"):
            vec = params[key]
            if key in params["given"] and len(vec) != size:
                raise line.fail(
                    f"element {written!r}: {key} has {len(vec)} entries for {size} inputs; "
                    "give one per input"
                )
            if len(vec) == 1 and size > 1:
                params[key] = vec * size
    law = _law(kind, params, line, written)
    pairs, currents, sensed = [], [], []  # sensed[k]: ("v", pair index) or ("i", index)
    for k, (kind_of, nodes) in enumerate(flat):
        if kind_of in ("v", "vd"):
            sensed.append(("v", len(pairs)))
            pairs.append(nodes if kind_of == "vd" else (nodes[0], "0"))
        elif kind_of == "vnam":
            if nodes[0][0].upper() != "V":
                raise line.fail(
                    f"element {written!r}: %vnam {nodes[0]!r} must name a voltage source"
                )
            sensed.append(("i", len(currents)))
            currents.append((nodes[0], ctx.ref(nodes[0])))
        else:  # %i, %id: a 0 V source from n+ to n− whose current is the input
            aux = f"{name}#{k}"
            a, b = nodes if kind_of == "id" else (nodes[0], "0")
            ctx.circuit.add(cp.VoltageSource(0.0, name=aux), p=ctx.node(a), n=ctx.node(b))
            ctx.circuit.origin[aux] = f"{line.where} ({ctx.display(written)}, input {k + 1})"
            sensed.append(("i", len(currents)))
            currents.append((None, aux))
    if out_type == "gd":  # the port's own voltage is the law's last input
        sensed.append(("v", len(pairs)))
        pairs.append(out_nodes)
    a, b = out_nodes if len(out_nodes) == 2 else (out_nodes[0], "0")

    def inputs(v, i):
        return [v[j] if which == "v" else i[j] for which, j in sensed]

    derivatives = ()
    if kind == "d_dt":  # its law reads d/dt of its input: a held position (ddt's)
        derivatives = (lambda v, i, t: inputs(v, i)[0],)

    def f(v, i, t, d):
        return law([d[0]] if derivatives else inputs(v, i))

    nodes = {"p": a, "n": b}
    for k, (n1, n2) in enumerate(pairs):
        nodes[f"c{k}p"], nodes[f"c{k}n"] = n1, n2
    ctx.reader.name_checks.append(
        (line, ctx, written, [n for pair in pairs for n in pair],
         [w for w, _ in currents if w is not None])
    )  # fmt: skip
    part = cp.BehaviouralSource(
        "V" if out_type in ("v", "vd") else "I",
        f,
        name=name,
        pairs=len(pairs),
        currents=[c for _, c in currents],
        derivatives=derivatives,
        tau=ctx.tran[1] if ctx.tran else cp.behavioural.TAU,  # TSTOP: see TAU
    )
    return part, nodes


def _int(ctx, name, line, p, inp, out_type, out_nodes, written):
    """``int`` (module docstring): the integral as the charge of a 1 F capacitor at a
    hidden node ``<instance>#int`` fed the current ``gain·(x + in_offset)``, its output an
    ideal source of that node's voltage through ``limit``'s smooth clamp."""
    lo, hi, d = p["out_lower_limit"], p["out_upper_limit"], p["limit_range"]
    if not d > 0.0 or hi - lo < 2.0 * d:
        raise line.fail(
            f"element {written!r}: int needs limit_range > 0 and out_upper_limit − "
            f"out_lower_limit ≥ 2·limit_range (got L={lo:g}, U={hi:g}, range {d:g})"
        )
    if not lo + d <= p["out_ic"] <= hi - d:
        raise line.fail(
            f"element {written!r}: int's out_ic={p['out_ic']:g} is not inside "
            f"[out_lower_limit + limit_range, out_upper_limit − limit_range] = "
            f"[{lo + d:g}, {hi - d:g}]; move out_ic or the limits"
        )
    kind_of, nodes = inp
    a, b = nodes if kind_of == "vd" else (nodes[0], "0")
    local = f"{written}#int".lower()  # a node of the line's scope, so its path prefixes it
    hidden = ctx.node(local)
    # the hidden node starts at out_ic: held there by the operating point (as a .ic
    # node is), the capacitor's initial voltage with UIC
    ctx.reader.ic[hidden] = p["out_ic"]
    cap = cp.Capacitor(1.0, name=f"{name}#c", v0=p["out_ic"], negative=True)
    ctx.circuit.add(cap, p=hidden, n="0")
    feed = cp.BehaviouralSource(
        "I",
        lambda v, i, t, dd: p["gain"] * (v[0] + p["in_offset"]),
        name=f"{name}#i",
        pairs=1,
    )  # an I source's current runs from p through it to n: n = the hidden node charges it
    ctx.circuit.add(feed, p="0", n=hidden, c0p=ctx.node(a), c0n=ctx.node(b))
    where = f"{line.where} ({ctx.display(written)})"
    ctx.circuit.origin[f"{name}#c"] = ctx.circuit.origin[f"{name}#i"] = where
    ctx.reader.name_checks.append((line, ctx, written, [a, b], []))
    ctx.note(
        line,
        f"{written}: int's limits clamp its output; ngspice also clamps its integral "
        "state there, so once the integral passes a limit ± limit_range the two differ",
    )
    out = cp.BehaviouralSource(
        "V",
        lambda v, i, t, dd: _clamp(v[0], lo, hi, d),
        name=name,
        pairs=1,
    )
    po, no = out_nodes if len(out_nodes) == 2 else (out_nodes[0], "0")
    return out, {"p": po, "n": no, "c0p": local, "c0n": "0"}


def _memristor(ctx, name, line, p, nodes, written):
    """``memristor`` (module docstring): :func:`~diracvi.components.Memristor` on the
    port, its state ``R`` the voltage of a hidden node ``<instance>#r`` held by a 1 F
    capacitor charged to ``rinit``."""
    try:
        part = cp.Memristor(
            p["rmin"], p["rmax"], p["rinit"], p["alpha"], p["beta"], p["vt"], name=name
        )
    except ModelError as exc:
        raise line.fail(f"element {written!r}: {exc}") from None
    local = f"{written}#r".lower()  # a node of the line's scope, so its path prefixes it
    hidden = ctx.node(local)
    # held at rinit by the operating point (as a .ic node is: ngspice's DC answer is
    # V/rinit), the capacitor's initial voltage with UIC
    ctx.reader.ic[hidden] = p["rinit"]
    ctx.circuit.add(cp.Capacitor(1.0, name=f"{name}#c", v0=p["rinit"]), p=hidden, n="0")
    ctx.circuit.origin[f"{name}#c"] = f"{line.where} ({ctx.display(written)})"
    ctx.reader.name_checks.append((line, ctx, written, list(nodes), []))
    return part, {"p": nodes[0], "n": nodes[1], "h": local, "g": "0"}


def corner(x, x0, y0, d, s_lo, s_hi):
    """ngspice's ``cm_smooth_corner``: the parabola tangent to the line of slope ``s_lo``
    through ``(x0, y0)`` at ``x0 − d`` and to that of slope ``s_hi`` at ``x0 + d``."""
    return y0 + s_lo * (x - x0) + (s_hi - s_lo) * (x - x0 + d) ** 2 / (4.0 * d)


def _clamp(u, lo, hi, d):
    """``limit``'s output (module docstring) of the unlimited ``u``; ``d > 0``."""
    upper = jnp.where(u > hi - d, jnp.where(u < hi + d, corner(u, hi, hi, d, 1.0, 0.0), hi), u)
    lower = jnp.where(u > lo - d, corner(u, lo, lo, d, 0.0, 1.0), lo)
    return jnp.where(u < lo + d, lower, upper)


def _law(kind, p, line, written):
    """``f(xs)``: the model's output from its inputs (module docstring)."""
    if kind == "gain":
        return lambda xs: p["out_offset"] + p["gain"] * (xs[0] + p["in_offset"])
    if kind == "summer":
        return lambda xs: p["out_gain"] * sum(
            g * (x + o) for g, x, o in zip(p["in_gain"], xs, p["in_offset"], strict=True)
        ) + p["out_offset"]  # fmt: skip
    if kind == "mult":
        gains = math.prod(p["in_gain"])

        def mult(xs):
            prod = 1.0
            for x, o in zip(xs, p["in_offset"], strict=True):
                prod = prod * (x + o)
            return prod * gains * p["out_gain"] + p["out_offset"]

        return mult
    if kind == "divide":
        big_l = p["den_lower_limit"]
        dom = p["den_domain"] * (big_l if p["fraction"] else 1.0)
        if big_l < 1e-10 or not dom > 0.0:
            raise line.fail(
                f"element {written!r}: divide needs den_lower_limit ≥ 1e-10 and den_domain "
                f"> 0 (got {big_l:g}, {dom:g})"
            )

        def divide(xs):
            num = p["num_gain"] * (xs[0] + p["num_offset"])
            den = p["den_gain"] * (xs[1] + p["den_offset"])
            pos = jnp.where(den > big_l - dom, corner(den, big_l, big_l, dom, 0.0, 1.0), big_l)
            neg = jnp.where(
                den < -(big_l - dom), corner(den, -big_l, -big_l, dom, 0.0, 1.0), -big_l
            )
            lim = jnp.where(
                (den < big_l + dom) & (den >= 0.0),
                pos,
                jnp.where((den > -(big_l + dom)) & (den < 0.0), neg, den),
            )
            return p["out_offset"] + p["out_gain"] * num / lim

        return divide
    if kind == "limit":
        lo, hi = p["out_lower_limit"], p["out_upper_limit"]
        d = p["limit_range"] * ((hi - lo) if p["fraction"] else 1.0)
        if not d > 0.0 or hi - lo < 2.0 * d:
            raise line.fail(
                f"element {written!r}: limit needs limit_range > 0 and out_upper_limit − "
                f"out_lower_limit ≥ 2·limit_range (got L={lo:g}, U={hi:g}, range {d:g})"
            )
        return lambda xs: _clamp(p["gain"] * (xs[0] + p["in_offset"]), lo, hi, d)
    if kind == "d_dt":
        lo, hi, d = p["out_lower_limit"], p["out_upper_limit"], p["limit_range"]
        if not d > 0.0 or hi - lo < 2.0 * d:
            raise line.fail(
                f"element {written!r}: d_dt needs limit_range > 0 and out_upper_limit − "
                f"out_lower_limit ≥ 2·limit_range (got L={lo:g}, U={hi:g}, range {d:g})"
            )
        return lambda xs: _clamp(p["gain"] * xs[0] + p["out_offset"], lo, hi, d)
    if kind == "climit":
        if not p["limit_range"] > 0.0:
            raise line.fail(f"element {written!r}: climit needs limit_range > 0")

        def climit(xs):
            u = p["gain"] * (xs[0] + p["in_offset"])
            hi = xs[1] - p["upper_delta"]
            lo = xs[2] + p["lower_delta"]
            d = p["limit_range"] * ((hi - lo) if p["fraction"] else 1.0)
            ok = hi - lo >= 2.0 * d
            safe = jnp.where(ok & (d > 0.0), d, 1.0)
            return jnp.where(ok, _clamp(u, lo, hi, safe), 0.0)

        return climit
    if kind == "pwl":
        return _pwl(p, line, written)
    if kind == "aswitch":
        return _aswitch(p, line, written)
    return _zener(p, line, written)


def _pwl(p, line, written):
    xs, ys = list(p["x_array"]), list(p["y_array"])
    if len(xs) != len(ys) or len(xs) < 2 or any(b <= a for a, b in itertools.pairwise(xs)):
        raise line.fail(
            f"element {written!r}: pwl needs x_array and y_array of one length ≥ 2 with "
            f"increasing x (got {len(xs)} and {len(ys)} entries)"
        )
    dom = p["input_domain"]
    if p["fraction"] and not 1e-12 <= dom <= 0.5:
        raise line.fail(f"element {written!r}: pwl input_domain={dom:g} must be in [1e-12, 0.5]")
    segs = [u - t for t, u in itertools.pairwise(xs)]
    slopes = [(b - a) / g for (a, b), g in zip(itertools.pairwise(ys), segs, strict=True)]
    end_lo, end_hi = (0.0, 0.0) if p["limit"] else (slopes[0], slopes[-1])
    s = [end_lo, *slopes, end_hi]  # s[i]: slope left of point i is s[i], right s[i+1]
    seg = [segs[0], *segs, segs[-1]]
    widths = [dom * min(seg[i], seg[i + 1]) if p["fraction"] else dom for i in range(len(xs))]
    if not p["fraction"] and any(2.0 * dom > g for g in segs):
        raise line.fail(
            f"element {written!r}: pwl input_domain={dom:g} (absolute, fraction=FALSE) is more "
            f"than half of a segment ({min(segs):g}); ngspice warns 'violation of 50% rule' "
            "— use a smaller input_domain or fraction=TRUE"
        )

    def pwl(args):
        x = args[0]
        # the polyline through (x_i, y_i), continued by s[0] and s[-1]: a sum of hinges
        out = ys[0] + s[0] * (x - xs[0])
        for i, xi in enumerate(xs):
            out = out + (s[i + 1] - s[i]) * jnp.maximum(x - xi, 0.0)
        # each corner's parabola minus the polyline: (Δs/4d)·max(d − |x − x_i|, 0)²
        for i, xi in enumerate(xs):
            if s[i + 1] != s[i]:
                gap = jnp.maximum(widths[i] - jnp.abs(x - xi), 0.0)
                out = out + (s[i + 1] - s[i]) * gap**2 / (4.0 * widths[i])
        return out

    return pwl


def _aswitch(p, line, written):
    on, off = p["cntl_on"], p["cntl_off"]
    r_on, r_off = max(p["r_on"], 1e-3), p["r_off"]
    if abs(on - off) < 1e-12 or (p["log"] and not r_off > 0.0):
        raise line.fail(
            f"element {written!r}: aswitch needs cntl_on ≠ cntl_off (ngspice: 'CONTROL "
            f"voltage delta less than 1.0e-12') and r_off > 0 (got {on:g}, {off:g}, {r_off:g})"
        )
    lo, hi = (math.log(r_on), math.log(r_off)) if p["log"] else (r_on, r_off)
    floor = math.log(1e-9) if p["log"] else 1e-9

    def aswitch(xs):
        x, v = xs
        if p["log"]:
            log_r = lo + (hi - lo) * (on - x) / (on - off)
            log_r = jnp.clip(log_r, lo, hi) if p["limit"] else jnp.maximum(log_r, floor)
            return v * jnp.exp(-log_r)
        r = r_on + (r_off - r_on) * (on - x) / (on - off)
        r = jnp.clip(r, min(lo, hi), max(lo, hi)) if p["limit"] else jnp.maximum(r, floor)
        return v / r

    return aswitch


#: the largest exponent the zener's branches take: e^600 is finite, so the branch
#: ``jnp.where`` does not select has a finite value and derivative (an ``inf`` there would
#: make the derivative NaN); no current in a circuit comes near ``i_sat·e^600``
_HUGE = 600.0


def _zener(p, line, written):
    r"""ngspice's ``zener`` current ``i(V)`` (``cm_zener``): with ``n vt`` the forward
    scale (``vt`` = 0.026), ``k = 1/(i_breakdown · r_breakdown)``,
    ``V₁₂ = n vt ln(n vt/10)`` and ``V₂₃ = −v_breakdown + ln(10/(i_sat r_breakdown))/k``:

    - if ``V₂₃ < V₁₂``: ``i_sat (e^{V/n vt} − 1)`` above ``V₁₂``; the line
      ``(i_sat/10)(V − V₁₂) + i(V₁₂)`` down to ``V₂₃``; below it ``c − i₀ e^{−k(V − V₀)}``
      with ``i₀ = 1 µA``, ``V₀ = −v_breakdown + ln(i_breakdown/i₀)/k`` and ``c`` joining it
      to the line at ``V₂₃``;
    - else two segments: ``i_sat (e^{V/n vt} − 1)`` (``V ≥ 0``) and ``−i₀ (e^{−kV} − 1)``
      (``i₀ = i_breakdown/(e^{k v_breakdown} − 1)``), the shallower side given the
      other's slope at 0 added linearly;

    plus ``(i_rev/v_breakdown) V``."""
    vb, ib, rb = p["v_breakdown"], p["i_breakdown"], p["r_breakdown"]
    i_rev, i_sat, n = p["i_rev"], p["i_sat"], p["n_forward"]
    checks = [
        (1e-6 <= vb <= 1e6, "v_breakdown", vb, "[1e-6, 1e6]"),
        (ib >= 1e-9, "i_breakdown", ib, "≥ 1e-9"),
        (rb >= 1e-12, "r_breakdown", rb, "≥ 1e-12"),
        (i_rev >= 1e-9, "i_rev", i_rev, "≥ 1e-9"),
        (i_sat >= 1e-15, "i_sat", i_sat, "≥ 1e-15"),
        (0.1 <= n <= 10, "n_forward", n, "[0.1, 10]"),
    ]
    for ok, key, value, bound in checks:
        if not ok:
            raise line.fail(f"element {written!r}: zener {key}={value:g} must be in {bound}")
    nvt = n * 0.026
    v12 = nvt * math.log(nvt / 10.0)
    k = 1.0 / ib / rb
    v23 = -vb + math.log(10.0 / i_sat / rb) / k
    g = i_rev / vb
    if v23 < v12:
        i0 = 1e-6
        v0 = -vb + math.log(ib / i0) / k
        a = i_sat / 10.0
        b = i_sat * math.expm1(v12 / nvt) - a * v12
        c = a * v23 + b + i0 * math.exp(-k * (v23 - v0))

        def zener(xs):
            v = xs[0]
            fwd = i_sat * jnp.expm1(jnp.minimum(v / nvt, _HUGE))
            rev = c - i0 * jnp.exp(jnp.minimum(-k * (v - v0), _HUGE))
            mid = a * v + b
            return jnp.where(v >= v12, fwd, jnp.where(v >= v23, mid, rev)) + g * v

        return zener
    i0 = ib / math.expm1(k * vb)
    s1, s2 = i_sat / nvt, i0 * k

    def zener2(xs):
        v = xs[0]
        fwd = i_sat * jnp.expm1(jnp.minimum(v / nvt, _HUGE)) + max(s2 - s1, 0.0) * v
        rev = -i0 * jnp.expm1(jnp.minimum(-k * v, _HUGE)) + max(s1 - s2, 0.0) * v
        return jnp.where(v >= 0.0, fwd, rev) + g * v

    return zener2
