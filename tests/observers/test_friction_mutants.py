"""The RTOB's Coulomb term: tests that kill the mutants benchmarks/mutation.py found
surviving."""

from __future__ import annotations

import dataclasses

import pytest

from hpdob.observers import CoulombFriction


def test_a_coulomb_term_cannot_be_changed_after_it_is_made():
    # A design keeps the term and its kernel record is derived from it once: a term changed in
    # place would leave the two apart (survivor: @dataclass(frozen=False), 2026-12-02).
    term = CoulombFriction(0.01, 0.01, deadband=0.02)
    with pytest.raises(dataclasses.FrozenInstanceError):
        term.deadband = 0.0
    assert term.deadband == 0.02
    assert hash(term) == hash(CoulombFriction(0.01, 0.01, deadband=0.02))
