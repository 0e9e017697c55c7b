"""The Adam loop both stages share: warm-up, reduce-on-plateau with return to the best parameters, early stop, checkpoints."""

from __future__ import annotations

from typing import Callable, Sequence

import numpy as np
import torch

from warpskill.engine.warp_bridge import copy_into
from warpskill.optimizer.checkpoint import Checkpoint
from warpskill.optimizer.config import OptimizeConfig
from warpskill.progress import progress_bar


def minimise(
    modules: Sequence[torch.nn.Module],
    objective: Callable[[list[int]], list[dict[str, torch.Tensor]]],
    *,
    iterations: int,
    learning_rate: float,
    config: OptimizeConfig,
    progress: bool,
    label: str,
    store: "Checkpoint",
    rivals: Sequence[object | None] | None = None,
    rungs: Sequence[tuple[int, float]] = (),
    coarse: tuple[int, Callable[[list[int]], list[dict[str, torch.Tensor]]]] | None = None,
) -> list[float]:
    """Adam (amsgrad) with reduce-on-plateau, per module; leaves each module at its best parameters.

    ``objective(live)`` returns the named loss terms of the modules ``live`` (indices), whose
    sums are minimised. Each module has its own learning rate and schedule (its own Adam
    parameter group) and stops once its rate has decayed; the others go on.

    ``rivals`` gives each module a group (None: none) and ``rungs`` a list of (iteration,
    margin): after that many iterations, a module whose best loss is more than ``margin``
    (relative) above the best of its group stops where it is (successive halving: a
    hypothesis far behind early seldom wins late; near ties go on to a later rung).

    ``coarse`` = (K, coarse objective): the first K iterations minimise the coarse objective (the
    same terms at a lower resolution); then each module restarts from its best parameters with
    its best loss and schedule forgotten (the two losses differ in scale).

    A module also stops once it has converged: its best loss fell by less than
    ``config.converge_tolerance`` (relative) over the last ``config.converge_window`` iterations.

    Returns:
        The best loss each module reached.
    """
    run = _AdamRun(modules, learning_rate, config, store, label)
    bar = progress_bar(total=iterations, initial=run.start, desc=label, enabled=progress, leave=False)
    iteration = run.start
    switch, coarse_objective = coarse or (0, objective)
    while iteration < iterations and (active := run.live()):
        if iteration == switch > 0:
            run.restart()
        run.optimizer.zero_grad(set_to_none=True)  # modules that have stopped get no gradient: Adam skips them
        terms = (coarse_objective if iteration < switch else objective)(active)
        losses = torch.stack([sum(t.values()) for t in terms])
        values = losses.detach().cpu().tolist()  # the iteration's one device-to-host copy
        run.check_finite(active, values, iteration)
        losses.sum().backward()
        run.step(active, values, iteration)
        iteration += 1
        run.stop(run.converged(active))
        for rung, margin in rungs if rivals is not None else ():
            if iteration == rung:
                run.stop(_behind_rivals(rivals, run.best_loss, margin))
        bar.update(1)
        bar.set_postfix(run.postfix(active))
        if iteration % config.checkpoint_every == 0:
            run.save(iteration)
    bar.close()
    return run.finish(objective, iterations)


class _AdamRun:
    """The state of one :func:`minimise` call: Adam, each module's plateau schedule, best loss
    and parameters, resumed from and saved to the checkpoint under ``label``."""

    def __init__(self, modules: Sequence[torch.nn.Module], learning_rate: float, config: OptimizeConfig,
                 store: Checkpoint, label: str):
        self.modules, self.learning_rate, self.config, self.store, self.label = modules, learning_rate, config, store, label
        self.optimizer = torch.optim.Adam([{"params": list(m.parameters())} for m in modules], lr=learning_rate,
                                          amsgrad=True, foreach=True)
        self.plateaus = [Plateau(config.plateau_patience, config.plateau_factor) for _ in modules]
        self.best_loss, self.best_state, self.start = [float("inf")] * len(modules), [copy_state(m) for m in modules], 0
        self.trail: list[list[float]] = [[] for _ in modules]  # each module's best loss after each of its iterations
        saved = store.load(label)
        if saved is not None:
            for module, state in zip(modules, saved["modules"]):
                module.load_state_dict(state)
            self.optimizer.load_state_dict(saved["optimizer"])
            for plateau, state in zip(self.plateaus, saved["plateaus"]):
                plateau.best, plateau.bad = state
            self.best_loss, self.best_state, self.start = saved["best_loss"], saved["best_state"], saved["iteration"]
            self.trail = saved.get("trail", self.trail)
        self.groups = self.optimizer.param_groups  # after loading: load_state_dict replaces the group dicts
        # The progress bar sums over every module: its latest loss (a stopped module's last)
        # beside its best, so the two totals are of the same quantity and best <= loss.
        self.latest = list(self.best_loss)

    def live(self) -> list[int]:
        """The modules whose learning rate has not decayed below ``min_lr_ratio`` of its start."""
        floor = self.learning_rate * self.config.min_lr_ratio
        return [b for b in range(len(self.modules)) if self.groups[b]["lr"] >= floor]

    def check_finite(self, active: list[int], values: list[float], iteration: int) -> None:
        """Raise FloatingPointError naming the scene whose loss is NaN or infinite."""
        for b, value in zip(active, values):
            if not np.isfinite(value):
                which = f" (scene {b})" if len(self.modules) > 1 else ""
                raise FloatingPointError(f"{self.label}{which}: the loss became {value} at iteration {iteration}")

    def step(self, active: list[int], values: list[float], iteration: int) -> None:
        """Record the losses, take one Adam step (warmed up), lower plateaued rates."""
        lr_before = [group["lr"] for group in self.groups]
        for b, value in zip(active, values):
            self.latest[b] = value
            if value < self.best_loss[b]:
                self.best_loss[b] = value
                keep_state(self.modules[b], self.best_state[b])
            self.trail[b] = (self.trail[b] + [self.best_loss[b]])[-(self.config.converge_window + 1):]
            # Warm-up: Adam's first steps move every parameter by about lr, whatever its gradient,
            # which can push the hand out of a grasp that only just holds.
            self.groups[b]["lr"] = lr_before[b] * min(1.0, (iteration + 1) / self.config.warmup_iterations)
        self.optimizer.step()
        for b, value in zip(active, values):
            self.groups[b]["lr"] = lr_before[b]
            if self.plateaus[b].step(value, self.groups[b]):
                # Back to the best parameters, and forget the momentum that led away from them.
                self.modules[b].load_state_dict(self.best_state[b])
                for parameter in self.modules[b].parameters():
                    self.optimizer.state.pop(parameter, None)

    def converged(self, active: list[int]) -> list[int]:
        """The ``active`` modules whose best loss fell by less than ``converge_tolerance`` (relative)
        over their last ``converge_window`` iterations (none while the window is 0)."""
        window, tolerance = self.config.converge_window, self.config.converge_tolerance
        return [b for b in active if window > 0 and len(self.trail[b]) > window
                and self.trail[b][0] - self.trail[b][-1] <= tolerance * abs(self.trail[b][0])]

    def restart(self) -> None:
        """Every module back at its best parameters, its best loss, plateau and trail forgotten."""
        for b, module in enumerate(self.modules):
            module.load_state_dict(self.best_state[b])
        self.best_loss = [float("inf")] * len(self.modules)
        self.plateaus = [Plateau(self.config.plateau_patience, self.config.plateau_factor) for _ in self.modules]
        self.trail = [[] for _ in self.modules]

    def stop(self, modules: list[int]) -> None:
        """Stop these modules where they are."""
        for b in modules:
            self.groups[b]["lr"] = 0.0

    def postfix(self, active: list[int]) -> dict[str, str]:
        """The progress bar's numbers: summed latest and best loss, a running module's rate."""
        count = len(self.modules)
        return {"loss": f"{sum(self.latest):.4f}", "best": f"{sum(self.best_loss):.4f}",
                "lr": f"{self.groups[active[0]]['lr']:.1e}", **({"running": f"{len(active)}/{count}"} if count > 1 else {})}

    def save(self, iteration: int) -> None:
        """Checkpoint everything needed to resume after ``iteration`` iterations."""
        self.store.save(self.label, dict(
            modules=[m.state_dict() for m in self.modules], optimizer=self.optimizer.state_dict(),
            plateaus=[(p.best, p.bad) for p in self.plateaus], best_loss=self.best_loss, best_state=self.best_state,
            iteration=iteration, trail=self.trail,
        ))

    def finish(self, objective, iterations: int) -> list[float]:
        """Leave every module at its best parameters, save, and return the best losses."""
        unrun = [b for b in range(len(self.modules)) if self.best_loss[b] == float("inf")]
        if unrun:  # no iteration ran: report the loss where the parameters are
            with torch.no_grad():
                for b, terms in zip(unrun, objective(unrun)):
                    self.best_loss[b] = float(sum(terms.values()))
        for module, state in zip(self.modules, self.best_state):
            module.load_state_dict(state)
        self.save(iterations)
        return self.best_loss


def _behind_rivals(rivals: Sequence[object | None], best_loss: Sequence[float], margin: float) -> list[int]:
    """The modules whose loss is more than ``margin`` (relative) above the lowest of their group."""
    lowest: dict[object, float] = {}
    for group, loss in zip(rivals, best_loss):
        if group is not None:
            lowest[group] = min(loss, lowest.get(group, float("inf")))
    return [b for b, (group, loss) in enumerate(zip(rivals, best_loss))
            if group is not None and loss > (1.0 + margin) * lowest[group]]


class Plateau:
    """Reduce-on-plateau for one parameter group (``torch.optim.lr_scheduler.ReduceLROnPlateau``'s
    rule: relative threshold 1e-4, no cool-down)."""

    def __init__(self, patience: int, factor: float):
        self.patience, self.factor = patience, factor
        self.best, self.bad = float("inf"), 0

    def step(self, value: float, group: dict) -> bool:
        """Record ``value``; return whether ``group``'s learning rate was lowered."""
        if value < self.best * (1.0 - 1e-4):
            self.best, self.bad = value, 0
        else:
            self.bad += 1
        if self.bad <= self.patience:
            return False
        self.bad = 0
        lowered = group["lr"] * self.factor
        if group["lr"] - lowered <= 1e-8:
            return False
        group["lr"] = lowered
        return True


def copy_state(module: torch.nn.Module) -> dict[str, torch.Tensor]:
    """A detached copy of ``module``'s parameters and buffers."""
    return {k: v.detach().clone() for k, v in module.state_dict().items()}


def keep_state(module: torch.nn.Module, state: dict[str, torch.Tensor]) -> None:
    """Overwrite ``state`` (a :func:`copy_state` of ``module``) with ``module``'s parameters and
    buffers now, in one multi-tensor copy."""
    live = module.state_dict(keep_vars=True)
    copy_into([state[name] for name in live], list(live.values()))
