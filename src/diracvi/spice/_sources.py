r"""Independent source specifications: ``[DC] value``, ``AC mag [phase]`` and a transient
function ``SIN``/``PULSE``/``PWL``/``EXP``/``SFFM``/``AM``, in any order, as ngspice reads them.

``V1 1 0 PULSE(0 1) AC 1`` and ``V1 1 0 DC 0 AC 1 SIN(0 1 1k)`` are both fine: the AC
specification belongs to a small-signal analysis, so it is noted and left out; with a
transient function, the DC value is the operating-point value, which ngspice replaces by
the function's value at t = 0 in a transient, so the function alone drives the run.
Defaults that ngspice takes from ``.tran`` (SIN's FREQ = 1/TSTOP; PULSE's TR, TF = TSTEP,
PW, PER = TSTOP; EXP's TD1, TAU1, TAU2 = TSTEP and TD2 = TD1 + TSTEP, each also when given
as 0 — ngspice's code, where its manual says TD1 = 0) are taken from it here too. PWL's
``TD=`` and ``R=`` (delay, repeat from a point) follow it after the list.
"""

from __future__ import annotations

from .. import components as cp
from ..errors import ModelError
from ._lines import NetlistError

FUNCTIONS = ("sin", "pulse", "pwl", "exp", "sffm", "am")
#: transient functions ngspice knows and diracvi does not build (refused by name), and why
OTHER_FUNCTIONS = {
    "trnoise": "transient noise is random: no two runs agree; rewrite it as a PWL",
    "trrandom": "random values: no two runs agree; rewrite it as a PWL",
    "external": "a value set from outside the simulator (shared ngspice); rewrite it as a PWL",
}
_KEYWORDS = ("dc", "ac", "distof1", "distof2")
#: other spellings ngspice accepts for a function (KiCad and eSim write SINE)
ALIASES = {"sine": "sin"}


def source(ctx, pos, kw, line):
    """The waveform of a ``V``/``I`` line (``pos[3:]`` is the specification)."""
    form = (
        f"{pos[0][0]}name n+ n- [[DC] value] [AC mag [phase]] "
        "[SIN(…) | PULSE(…) | EXP(…) | SFFM(…) | AM(…) | PWL(…) [TD=t] [R=t]]"
    )
    if len(pos) < 3:
        raise line.fail(f"expected '{form}' (a source has two nodes)")
    unknown = sorted(set(kw) - {"dc", "td", "r"})
    if unknown:
        raise line.fail(f"unsupported parameters {unknown} on a source (form: '{form}')")
    rest = pos[3:]
    fn = None
    dc = ctx.value(kw["dc"], line, "DC value") if "dc" in kw else None  # ngspice's DC=3
    args: list[str] = []
    k = 0
    while k < len(rest):
        word = ALIASES.get(rest[k].lower(), rest[k].lower())
        if word == "dc":
            if k + 1 >= len(rest) or _keyword(rest[k + 1]):
                # ngspice reads 'DC' with no value as DC 0 ('V1 1 0 DC PULSE(…)': .op 0 V,
                # the transient the PULSE; 'V2 2 0 DC': 0 V; ngspice 39)
                dc, k = 0.0, k + 1
                continue
            dc, k = ctx.value(rest[k + 1], line, "DC value"), k + 2
        elif word in ("ac", "distof1", "distof2"):
            k += 1
            taken = 0
            while k < len(rest) and taken < 2 and not _keyword(rest[k]):
                k, taken = k + 1, taken + 1
            ctx.note(line, f"{word.upper()} specification ignored (a transient does not use it)")
        elif word in FUNCTIONS or word in OTHER_FUNCTIONS:
            if fn is not None:
                raise line.fail(f"two transient functions ({fn.upper()} and {word.upper()})")
            if word in OTHER_FUNCTIONS:
                raise line.fail(
                    f"source function {rest[k]!r} is not supported (diracvi builds DC, SIN, "
                    f"PULSE, EXP, SFFM, AM and PWL sources): {OTHER_FUNCTIONS[word]}"
                )
            fn, k = word, k + 1
            while k < len(rest) and not _keyword(rest[k]):
                args.append(rest[k])
                k += 1
        elif dc is None and k == 0:
            dc, k = ctx.value(rest[0], line, "value"), 1
        else:
            raise line.fail(f"unexpected {rest[k]!r} in a source specification (form: '{form}')")
    pwl_options = {k: kw[k] for k in ("td", "r") if k in kw}
    if pwl_options and fn != "pwl":
        raise line.fail(
            f"{' and '.join(k.upper() + '=' for k in pwl_options)} "
            f"{'belong' if len(pwl_options) > 1 else 'belongs'} to a PWL source "
            f"(form: '{form}'); remove them or write the waveform as a PWL"
        )
    if fn is None:
        if dc is None:
            dc = 0.0  # ngspice: a source with only an AC spec is 0 in a transient
        return cp.DC(dc)
    values = [ctx.value(t, line, fn.upper()) for t in args]
    options = {k: ctx.value(v, line, f"PWL {k.upper()}") for k, v in pwl_options.items()}
    try:
        return _function(ctx, fn, values, line, options)
    except NetlistError:
        raise
    except ModelError as exc:
        raise line.fail(str(exc)) from None


def _keyword(token: str) -> bool:
    word = ALIASES.get(token.lower(), token.lower())
    return word in _KEYWORDS or word in FUNCTIONS or word in OTHER_FUNCTIONS


def _function(ctx, fn, args, line, options):
    step, stop = ctx.tran or (None, None)
    if fn == "sin":
        if not 2 <= len(args) <= 6:
            raise line.fail("SIN(VO VA [FREQ [TD [THETA [PHASE]]]]) takes 2 to 6 values")
        if len(args) < 3 or args[2] == 0.0:  # ngspice: FREQ 0 or absent → 1/TSTOP
            if stop is None:
                raise line.fail("SIN FREQ defaults to 1/TSTOP, but there is no '.tran'; give it")
            args[2:3] = [1.0 / stop]
        return cp.Sine(*args)
    if fn == "pulse":
        if not 2 <= len(args) <= 8:
            raise line.fail("PULSE(V1 V2 [TD [TR [TF [PW [PER [NP]]]]]]) takes 2 to 8 values")
        defaults = [0.0, step, step, stop, stop]
        full = (
            args[:2]
            + [
                args[2 + j] if 2 + j < len(args) and (j == 0 or args[2 + j] > 0) else d
                for j, d in enumerate(defaults)
            ]
            + args[7:]
        )
        if any(x is None for x in full):
            raise line.fail("PULSE defaults TR, TF, PW, PER come from '.tran'; add one")
        return cp.Pulse(*full)
    if fn == "exp":
        if not 2 <= len(args) <= 6:
            raise line.fail("EXP(V1 V2 [TD1 [TAU1 [TD2 [TAU2]]]]) takes 2 to 6 values")
        if step is None and not (len(args) == 6 and all(args[2:])):
            raise line.fail("EXP defaults TD1, TAU1, TD2, TAU2 come from '.tran'; add one")
        given = [args[j] if j < len(args) and args[j] != 0.0 else None for j in range(2, 6)]
        td1 = given[0] if given[0] is not None else step
        tau1 = given[1] if given[1] is not None else step
        td2 = given[2] if given[2] is not None else td1 + step
        tau2 = given[3] if given[3] is not None else step
        return cp.Exp(args[0], args[1], td1, tau1, td2, tau2)
    if fn == "sffm":
        if not 2 <= len(args) <= 8:
            raise line.fail(
                "SFFM(VO VA [FC [MDI [FS [PHASEC [PHASES]]]]]) takes 2 to 7 values (an 8th "
                "is read and ignored, as ngspice 39 does)"
            )
        # ngspice 39: FC and FS absent or 0 → 1/TSTOP, MDI absent → 0
        args = args + [0.0] * (5 - len(args))
        if (args[2] == 0.0 or args[4] == 0.0) and stop is None:
            raise line.fail("SFFM FC and FS default to 1/TSTOP, but there is no '.tran'; give them")
        args[2] = args[2] or 1.0 / stop
        args[4] = args[4] or 1.0 / stop
        if len(args) > 5:
            ctx.note(
                line,
                "SFFM's 6th and 7th values read as ngspice 39 reads them, the carrier's and "
                "the signal's phases in degrees (ngspice 46 reads TD and PHASEM there)"
                + (", its 8th ignored as ngspice 39 ignores it" if len(args) > 7 else ""),
            )
        return cp.SFFM(*args[:7])
    if fn == "am":
        if not 2 <= len(args) <= 8:
            raise line.fail(
                "AM(VA VO [MF [FC [TD [PHASEC [PHASES]]]]]) takes 2 to 7 values (ngspice 39's "
                "order; an 8th is read and ignored, as ngspice 39 does)"
            )
        # ngspice 39 (vsrcload.c): MF absent or 0 → 1/TSTOP; FC, TD absent → 0
        args = args + [0.0] * (3 - len(args))
        if args[2] == 0.0:
            if stop is None:
                raise line.fail("AM MF defaults to 1/TSTOP, but there is no '.tran'; give it")
            args[2] = 1.0 / stop
        ctx.note(
            line,
            "AM read as ngspice 39 reads it, AM(VA VO MF FC TD PHASEC PHASES): u = VA·(VO + "
            "sin(2π·MF·t′ + PHASES))·sin(2π·FC·t′ + PHASES), t′ = t − TD, 0 up to TD "
            "(ngspice 46 reads AM(VO VMO VMA FM FC TD PHASEM PHASEC))",
        )
        return cp.AM(*args[:7])
    if len(args) < 2 or len(args) % 2:
        raise line.fail("PWL(T1 V1 T2 V2 …) takes pairs of values")
    return cp.PWL(args[0::2], args[1::2], options.get("td", 0.0), options.get("r"))
