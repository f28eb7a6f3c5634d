"""BSIM4 cards shared by ``tests/test_bsim4.py``: the NMOS and PMOS cards of the corpus
deck ``ng_ro_17_4.cir`` (ngspice's BSIM4 examples: VERSION 4.5.0, 1.4 nm oxide), read
from the committed deck with their refused modes (igcMod, igbMod, rbodyMod, rgateMod = 1)
switched to the defaults — every other value as written."""

from __future__ import annotations

import re
from pathlib import Path

DECK = Path(__file__).parent / "data" / "netlists" / "ng_ro_17_4.cir"
MODES_OFF = {"igcmod": "0", "igbmod": "0", "rbodymod": "0", "rgatemod": "0"}


def ro_card(name: str, keep=()) -> str:
    """The ``.model name`` card's parameters as ``key=value`` words (LEVEL dropped, the
    sweep deck sets it), its modes switched off (module docstring) but those named in
    ``keep`` (e.g. ``("igcmod", "igbmod")``), left as the deck has them."""
    text = DECK.read_text()
    start = text.lower().index(f".model  {name.lower()} ")
    lines = [text[start:].splitlines()[0]]
    for line in text[start:].splitlines()[1:]:
        if not line.startswith("+"):
            break
        lines.append(line[1:])
    pairs = re.findall(r"(\w+)\s*=\s*(\S+)", " ".join(lines))
    off = {k: x for k, x in MODES_OFF.items() if k not in keep}
    out = [f"{k}={off.get(k.lower(), v)}" for k, v in pairs if k.lower() != "level"]
    return " ".join(out)
