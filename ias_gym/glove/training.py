"""Training the per-person calibration networks with torch (paper section 2.4).

Only this module imports torch (the ``[glove]`` extra); the trained weights become numpy
arrays in a :class:`~ias_gym.glove.calibration.Calibration`, which is what profiles store and
what inference uses. Import it only to train::

    from ias_gym.glove.training import train_calibration

Each ``"ann"`` group of the layout is the paper's three-layer network (inputs, one tanh hidden
layer, linear outputs), trained on z-scored inputs and targets by full-batch L-BFGS with a
strong-Wolfe line search in float64 on one CPU thread, minimising the mean squared
normalised joint error plus ``weight_decay`` x the sum of squared weights. ``"linear"``
groups are least squares (:func:`~ias_gym.glove.calibration.fit_linear_group`). Everything
is reproducible from ``seed``: the initial weights come from a numpy generator (uniform
Glorot), L-BFGS has no randomness, one thread keeps the reductions in one order.
With 1600 training readings and 1500 iterations per network a person's calibration (index
5-24-3 and thumb 5-12-2 networks) trains in about 3 s on one core here.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

try:
    import torch
except ImportError as exc:  # pragma: no cover - depends on the environment
    raise ImportError(
        "training a glove calibration needs torch: pip install 'ias-gym[glove]'"
    ) from exc

from ias_gym.glove.calibration import (
    ANN_GROUPS,
    DEFAULT_MAX_ITER,
    DEFAULT_READINGS,
    HELD_OUT_FRACTION,
    LINEAR_GROUPS,
    PAPER_GROUPS,
    Calibration,
    CalibrationMetrics,
    GroupModel,
    GroupSpec,
    evaluate,
    fit_linear,
    fit_linear_group,
    group_data,
    normalisation,
)
from ias_gym.glove.hand import PersonParams
from ias_gym.glove.profile import DEFAULT_GLOVE_ID, Profile
from ias_gym.glove.sensor_model import CalibrationSession, record_session

#: L2 penalty on the weights (normalised units).
DEFAULT_WEIGHT_DECAY = 1e-7


@dataclass(frozen=True)
class TrainingReport:
    """How training went.

    Attributes:
        seconds: wall time of the whole calibration [s].
        group_seconds: per group [s].
        group_loss: final training loss per ANN group (mean squared normalised error).
        iterations: L-BFGS iterations per ANN group.
    """

    seconds: float
    group_seconds: dict[str, float]
    group_loss: dict[str, float]
    iterations: dict[str, int]


@contextmanager
def _one_thread() -> Iterator[None]:
    previous = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        yield
    finally:
        torch.set_num_threads(previous)


def _glorot(rng: np.random.Generator, rows: int, cols: int) -> NDArray[np.float64]:
    bound = np.sqrt(6.0 / (rows + cols))
    return rng.uniform(-bound, bound, size=(rows, cols))


def train_group(
    spec: GroupSpec,
    session: CalibrationSession,
    *,
    seed: int = 0,
    max_iter: int = DEFAULT_MAX_ITER,
    weight_decay: float = DEFAULT_WEIGHT_DECAY,
) -> tuple[GroupModel, float, int]:
    """Train one ANN group on ``session``.

    Returns:
        The model, its final loss and the L-BFGS iterations used.
    """
    x, y = group_data(spec, session)
    xm, xs = normalisation(x)
    ym, ys = normalisation(y)
    rng = np.random.default_rng([seed, len(spec.inputs), spec.hidden])
    n_in, n_out, h = len(spec.inputs), len(spec.outputs), spec.hidden
    params = [
        torch.tensor(_glorot(rng, h, n_in), requires_grad=True),
        torch.zeros(h, dtype=torch.float64, requires_grad=True),
        torch.tensor(_glorot(rng, n_out, h), requires_grad=True),
        torch.zeros(n_out, dtype=torch.float64, requires_grad=True),
    ]
    w1, b1, w2, b2 = params
    xt = torch.from_numpy((x - xm) / xs)
    yt = torch.from_numpy((y - ym) / ys)
    opt = torch.optim.LBFGS(
        params,
        lr=1.0,
        max_iter=max_iter,
        history_size=20,
        tolerance_grad=1e-10,
        tolerance_change=1e-13,
        line_search_fn="strong_wolfe",
    )

    def closure() -> torch.Tensor:
        opt.zero_grad()
        pred = torch.tanh(xt @ w1.T + b1) @ w2.T + b2
        loss = torch.mean((pred - yt) ** 2) + weight_decay * (w1.square().sum() + w2.square().sum())
        loss.backward()
        return loss

    with _one_thread():
        opt.step(closure)
        with torch.no_grad():
            loss = float(torch.mean((torch.tanh(xt @ w1.T + b1) @ w2.T + b2 - yt) ** 2))
    iterations = int(opt.state[params[0]].get("n_iter", 0))
    layers = tuple(
        (w.detach().numpy().copy(), b.detach().numpy().copy()) for w, b in ((w1, b1), (w2, b2))
    )
    model = GroupModel(spec.name, "ann", spec.inputs, spec.outputs, xm, xs, ym, ys, layers)
    return model, loss, iterations


def train_calibration(
    session: CalibrationSession,
    groups: Sequence[GroupSpec] = ANN_GROUPS,
    *,
    seed: int = 0,
    max_iter: int = DEFAULT_MAX_ITER,
    weight_decay: float = DEFAULT_WEIGHT_DECAY,
    on_group: Callable[[str], None] | None = None,
) -> tuple[Calibration, TrainingReport]:
    """Calibrate one person: an ANN per ``"ann"`` group, least squares per ``"linear"`` one.

    Args:
        session: the training readings (hold some out for :func:`evaluate`).
        groups: the layout (default :data:`~ias_gym.glove.calibration.ANN_GROUPS`).
        seed: seeds the initial weights.
        max_iter: L-BFGS iterations per network (a smaller budget trains faster, e.g. tests).
        weight_decay: L2 penalty on the weights.
        on_group: called with each group's name when it is done (e.g. a progress bar).

    Returns:
        The calibration (numpy) and a :class:`TrainingReport`.
    """
    t0 = time.perf_counter()
    models: list[GroupModel] = []
    seconds: dict[str, float] = {}
    losses: dict[str, float] = {}
    iterations: dict[str, int] = {}
    for k, spec in enumerate(groups):
        tg = time.perf_counter()
        if spec.kind == "ann":
            model, losses[spec.name], iterations[spec.name] = train_group(
                spec, session, seed=seed + 1000 * k, max_iter=max_iter, weight_decay=weight_decay
            )
        else:
            model = fit_linear_group(spec, session)
        models.append(model)
        seconds[spec.name] = time.perf_counter() - tg
        if on_group is not None:
            on_group(spec.name)
    report = TrainingReport(time.perf_counter() - t0, seconds, losses, iterations)
    return Calibration(tuple(models)), report


@dataclass(frozen=True, eq=False)
class CalibrationRun:
    """Everything one person's calibration produced (see :func:`calibrate_person`).

    Attributes:
        person: who was calibrated.
        train, held_out: the session's two parts.
        models: ``"ann"`` (shipped: :data:`ANN_GROUPS`), ``"linear"`` (least squares,
            :data:`LINEAR_GROUPS`, same training readings) and, with ``baselines`` (the
            default), ``"paper_ann"`` (index 2-10-3 on ψ1, ψ2, :data:`PAPER_GROUPS`) and
            ``"linear_free"`` (the linear one fitted on the free poses only: the paper's
            "optimal gains" that fail when thumb and index touch).
        metrics: held-out errors of each model.
        report: training report of the ``"ann"`` calibration.
        profile: the ``"ann"`` calibration as a profile (not yet saved).
    """

    person: PersonParams
    train: CalibrationSession
    held_out: CalibrationSession
    models: dict[str, Calibration]
    metrics: dict[str, CalibrationMetrics]
    report: TrainingReport
    profile: Profile


def calibrate_person(
    person: PersonParams,
    *,
    seed: int = 0,
    n_readings: int = DEFAULT_READINGS,
    glove_id: str = DEFAULT_GLOVE_ID,
    max_iter: int = DEFAULT_MAX_ITER,
    baselines: bool = True,
    on_group: Callable[[str], None] | None = None,
) -> CalibrationRun:
    """Record a session for ``person``, train and evaluate the ANN and the baselines.

    Args:
        person: who wears the glove.
        seed: seeds the session (poses, noise), the split and the initial weights.
        n_readings: readings in the session (:data:`HELD_OUT_FRACTION` held out).
        glove_id: stored in the profile.
        max_iter: L-BFGS iterations per network.
        baselines: also train the paper's index network (``"paper_ann"``) and fit
            ``"linear_free"``; False leaves them out (the profile is the same: it holds the
            ``"ann"`` calibration and the ``"linear"`` metrics), e.g. for a cached default
            calibration.
        on_group: called with each trained group's name (:func:`train_calibration`).
    """
    session = record_session(person, n_readings, seed=seed)
    train, held_out = session.split(HELD_OUT_FRACTION, seed=seed)
    ann, report = train_calibration(
        train, ANN_GROUPS, seed=seed, max_iter=max_iter, on_group=on_group
    )
    models = {"ann": ann, "linear": fit_linear(train, LINEAR_GROUPS)}
    if baselines:
        paper_groups = []  # the shipped groups, with the paper's index network instead
        for k, spec in enumerate(PAPER_GROUPS):
            if spec in ANN_GROUPS:
                paper_groups.append(ann.group(spec.name))
            else:
                paper_groups.append(
                    train_group(spec, train, seed=seed + 1000 * k, max_iter=max_iter)[0]
                )
        models["paper_ann"] = Calibration(tuple(paper_groups))
        models["linear_free"] = fit_linear(train.subset(~train.pinch), LINEAR_GROUPS)
    metrics = {name: evaluate(model, held_out) for name, model in models.items()}
    training = {
        "seed": seed,
        "n_train": len(train),
        "n_held_out": len(held_out),
        "n_pinch_train": int(train.pinch.sum()),
        "max_iter": max_iter,
        "seconds": round(report.seconds, 3),
        "groups": ann.describe(),
        "simulated_person": person.to_dict(),
        "linear_held_out": metrics["linear"].to_dict(),
    }
    profile = Profile(person.person_id, glove_id, ann, metrics["ann"], training=training)
    return CalibrationRun(person, train, held_out, models, metrics, report, profile)
