"""The library's skill templates (ias_gym.assist.skill_motions): demonstrations of one motion
by persons of different amplitude and speed are aligned before they are averaged."""

from __future__ import annotations

import numpy as np

from ias_gym.assist.skill_motions import align_demonstrations

TAU = np.arange(0.0, 3.0, 0.01)


def _seesaw(tau: np.ndarray) -> np.ndarray:
    """Two cycles of a see-saw (period 0.75 s) that fades in and out, then rest."""
    u = np.clip(tau / 1.5, 0.0, 1.0)
    return (np.sin(np.pi * u) ** 2 * np.sin(2 * np.pi * tau / 0.75) * (tau < 1.5))[:, None]


def test_the_persons_amplitudes_and_speeds_are_recovered_and_the_template_is_sharp() -> None:
    rng = np.random.default_rng(0)
    amps = np.exp(rng.normal(0.0, 0.1, 12))
    speeds = np.exp(rng.normal(0.0, 0.1, 12))
    demos = np.array([a * _seesaw(v * TAU) for a, v in zip(amps, speeds, strict=True)])
    mean, a_fit, v_fit = align_demonstrations(TAU, demos)
    # relative to the typical person: the fit's grid of speeds is 0.02 apart
    np.testing.assert_allclose(a_fit / a_fit.mean(), amps / amps.mean(), rtol=0.03)
    gm = np.exp(np.log(v_fit).mean())
    np.testing.assert_allclose(v_fit / gm, speeds / np.exp(np.log(speeds).mean()), atol=0.025)
    # the aligned template keeps the see-saw's amplitude; a plain mean blurs it
    typical = amps.mean() * _seesaw(np.exp(np.log(speeds).mean()) * TAU)
    assert np.ptp(demos.mean(axis=0)) < 0.9 * np.ptp(typical)
    assert abs(np.ptp(mean) / np.ptp(typical) - 1.0) < 0.05


def test_identical_demonstrations_are_their_own_template() -> None:
    demos = np.repeat(_seesaw(TAU)[None], 3, axis=0)
    mean, a_fit, v_fit = align_demonstrations(TAU, demos)
    np.testing.assert_allclose(mean, demos[0], atol=1e-12)
    np.testing.assert_allclose(a_fit, 1.0, atol=1e-12)
    np.testing.assert_allclose(v_fit, 1.0, atol=1e-12)
