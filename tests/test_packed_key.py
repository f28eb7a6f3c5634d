"""The program store's key of a packed interconnection — a netlist's system as the sparse
path's programs take it — prints each group of alike parts once (its first part's
skeleton, the members, every name), not each of its parts: on a 1000-stage ladder that
was 0.13 s per program key, and it grew with the element count (issue 30).

The key must still tell apart whatever a traced program can see: another element count,
another topology, a part with other static data or of another kind, another name or
order; and it must ignore values (they are the programs' inputs). The grouped key is
compared with the key that prints every skeleton in full (what it replaces) on the same
decks: the two must agree on which decks share a key.

White-box: reads ``Skeletons.groups`` (``diracvi.model.stacked``).
"""

from __future__ import annotations

import itertools

from diracvi import spice
from diracvi.bench.ladders import ladder
from diracvi.runtime.fingerprint import canonical

BASE = ladder(4)
VARIANTS = {
    "base": BASE,
    "other values": BASE.replace("R2 n1 m2 10", "R2 n1 m2 22").replace("C4 n4 0 1u", "C4 n4 0 3u"),
    "one stage more": ladder(5),
    "one stage less": ladder(3),
    "a capacitor moved": BASE.replace("C3 n3 0 1u", "C3 n2 0 1u"),
    "a capacitor with IC=": BASE.replace("C3 n3 0 1u", "C3 n3 0 1u IC=0.5"),
    "a resistor for an inductor": BASE.replace("L2 m2 n2 1m", "L2 m2 n2 1m\nR9 m2 n2 5").replace(
        "L2 m2 n2 1m\n", ""
    ),
    "a name": BASE.replace("R2 n1 m2 10", "R2b n1 m2 10"),
    "two lines swapped": BASE.replace("R2 n1 m2 10\nL2 m2 n2 1m", "L2 m2 n2 1m\nR2 n1 m2 10"),
}


def _keys(text: str) -> tuple[str, str]:
    """(the grouped key, the key with every skeleton printed in full) of a deck's packed
    system."""
    packed = spice.read(text).system._packed()
    grouped = canonical(packed)
    skeletons = packed.subsystems
    groups, skeletons.groups = skeletons.groups, None
    try:
        full = canonical(packed)
    finally:
        skeletons.groups = groups
    return grouped, full


def test_the_grouped_key_tells_apart_what_the_full_key_does():
    keys = {name: _keys(text) for name, text in VARIANTS.items()}
    for (a, (ga, fa)), (b, (gb, fb)) in itertools.combinations(keys.items(), 2):
        assert (ga == gb) == (fa == fb), (a, b)
    # values are inputs of the programs: the same key; every other change: another
    base = keys["base"][0]
    assert keys["other values"][0] == base
    others = [name for name in VARIANTS if name not in ("base", "other values")]
    assert all(keys[name][0] != base for name in others)
    assert len({keys[name][0] for name in others}) == len(others)


def test_the_grouped_key_does_not_print_a_skeleton_per_part():
    """A skeleton printed in full is thousands of characters; a stage (three parts) adds
    only its names, node tables and incidence to the grouped key."""
    (g100, f100), (g200, f200) = _keys(ladder(100)), _keys(ladder(200))
    per_stage_grouped = (len(g200) - len(g100)) / 100
    per_stage_full = (len(f200) - len(f100)) / 100
    assert per_stage_full > 2000
    assert per_stage_grouped < 400
