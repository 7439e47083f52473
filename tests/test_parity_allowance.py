"""The bias allowance of the multiscale checks (parity.agreement_beyond) on synthetic images
whose channels are 0.9999 correlated, as a grey scene's are: a bias within the allowance in
every channel passes, whatever its colour, and one beyond it fails, in the grey direction
(noisy) or in a colour direction (precise)."""

from __future__ import annotations

import numpy as np
import pytest

from parity import Estimate, agreement, agreement_beyond, within_allowance

K, CELLS = 64, 4
VALUE = np.array([0.5, 0.4, 0.3])  # a cell's colour


def images(bias: np.ndarray, seed: int) -> Estimate:
    """K images of CELLS cells times 1 + bias: grey noise 8 % and colour noise 0.08 % per image
    (1 % and 0.01 % on the mean of K)."""
    rng = np.random.default_rng(seed)
    grey = 1 + 0.08 * rng.standard_normal((K, 1, CELLS, 1))
    colour = 1 + 8e-4 * rng.standard_normal((K, 1, CELLS, 3))
    return Estimate(VALUE * (1 + bias) * grey * colour)


@pytest.mark.parametrize(
    "bias, allowance, passes",
    [
        ([-0.036, -0.044, -0.044], 0.04, True),  # within in every channel, not alike
        ([0.03, -0.03, 0.0], 0.035, True),  # a colour shift within the allowance
        ([0.03, -0.03, 0.0], 0.01, False),  # beyond it, in a precise colour direction
        ([-0.12, -0.12, -0.12], 0.02, False),  # beyond it in grey, beyond the noise
    ],
)
def test_a_bias_is_judged_beyond_its_allowance(bias, allowance, passes):
    ours, reference = images(np.array(bias), 1), images(np.zeros(3), 2)
    result = agreement_beyond(ours, reference, allowance)
    assert result.passes == passes, result


def test_moving_each_channel_alone_is_not_enough():
    """The case agreement_beyond's chi-square exists for: each channel moved towards the
    reference by at most the allowance leaves a colour difference the chi-square rejects."""
    ours, reference = images(np.array([-0.036, -0.044, -0.044]), 1), images(np.zeros(3), 2)
    assert not agreement(within_allowance(ours, reference, 0.04), reference).passes
    assert agreement_beyond(ours, reference, 0.04).passes
