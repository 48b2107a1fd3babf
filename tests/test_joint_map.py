"""The encoder <-> DH joint map (docs/protocol.md, Encoder map), both ways, for positions and
increments."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from manus.joint_map import (
    dh_increments_to_encoder,
    dh_to_encoder,
    dh_to_encoder_list,
    encoder_increments_to_dh,
    encoder_increments_to_dh_list,
    encoder_to_dh,
)

vec = st.lists(st.floats(-20, 20, allow_nan=False), min_size=6, max_size=6).map(np.array)


def test_spec_formulas_in_degrees() -> None:
    e = np.radians([10.0, 20.0, 30.0, 40.0, 50.0, 60.0])
    q = np.degrees(encoder_to_dh(e))
    # q1 = e1, q2 = -e2, q3 = e3 - e2 + 90, q4 = e4 + 90, q5 = e5, q6 = e6
    assert q == pytest.approx([10.0, -20.0, 100.0, 130.0, 50.0, 60.0])


def test_increment_formulas() -> None:
    dq = np.array([1.0, 2.0, 3.0, 4.0, 5.0, 6.0])
    # de1 = dq1, de2 = -dq2, de3 = dq3 - dq2, de4..6 = dq4..6 ("add joint 2's increment to 3's")
    assert dh_increments_to_encoder(dq) == pytest.approx([1.0, -2.0, 1.0, 4.0, 5.0, 6.0])


@given(vec)
def test_positions_round_trip(e: np.ndarray) -> None:
    assert dh_to_encoder(encoder_to_dh(e)) == pytest.approx(e, abs=1e-12)
    assert encoder_to_dh(dh_to_encoder(e)) == pytest.approx(e, abs=1e-12)


@given(vec, vec)
def test_increments_are_differences_of_positions(e: np.ndarray, de: np.ndarray) -> None:
    dq = encoder_to_dh(e + de) - encoder_to_dh(e)
    assert encoder_increments_to_dh(de) == pytest.approx(dq, abs=1e-9)
    assert dh_increments_to_encoder(dq) == pytest.approx(de, abs=1e-9)


def test_batches_of_rows() -> None:
    e = np.arange(12.0).reshape(2, 6)
    assert encoder_to_dh(e).shape == (2, 6)
    assert np.allclose(dh_to_encoder(encoder_to_dh(e)), e)


@given(vec)
def test_scalar_twins_equal_the_matrix_forms(v: np.ndarray) -> None:
    # Equal to the last bit (== also equates 0.0 and -0.0); the twins never give -0.0,
    # so a zero rate encodes the same MessagePack bytes whatever the other joints do.
    for twin, matrix in (
        (dh_to_encoder_list, dh_to_encoder),
        (encoder_increments_to_dh_list, encoder_increments_to_dh),
    ):
        got = twin(v.tolist())
        assert got == matrix(v).tolist()
        assert all(type(x) is float for x in got)
    zeros = encoder_increments_to_dh_list([0.0, 0.0, 0.0, -0.0, -0.0, 0.0])
    assert all(str(x) == "0.0" for x in zeros)
