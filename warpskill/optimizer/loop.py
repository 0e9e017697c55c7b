"""The Adam loop both stages share: warm-up, reduce-on-plateau with return to the best parameters, early stop, checkpoints."""

from __future__ import annotations

from typing import Callable, Sequence

import numpy as np
import torch
from tqdm.auto import tqdm

from warpskill.optimizer.checkpoint import Checkpoint
from warpskill.optimizer.config import OptimizeConfig


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
) -> list[float]:
    """Adam (amsgrad) with reduce-on-plateau, per module; leaves each module at its best parameters.

    ``objective(live)`` returns the named loss terms of the modules ``live`` (indices), whose
    sums are minimised. Each module has its own learning rate and schedule (its own Adam
    parameter group) and stops once its rate has decayed; the others go on.

    ``rivals`` gives each module a group (None: none) and ``rungs`` a list of (iteration,
    margin): after that many iterations, a module whose best loss is more than ``margin``
    (relative) above the best of its group stops where it is (successive halving: a
    hypothesis far behind early seldom wins late; near ties go on to a later rung).

    Returns:
        The best loss each module reached.
    """
    count = len(modules)
    optimizer = torch.optim.Adam([{"params": list(m.parameters())} for m in modules], lr=learning_rate, amsgrad=True)
    plateaus = [Plateau(config.plateau_patience, config.plateau_factor) for _ in modules]
    best_loss, best_state, start = [float("inf")] * count, [copy_state(m) for m in modules], 0
    saved = store.load(label)
    if saved is not None:
        for module, state in zip(modules, saved["modules"]):
            module.load_state_dict(state)
        optimizer.load_state_dict(saved["optimizer"])
        for plateau, state in zip(plateaus, saved["plateaus"]):
            plateau.best, plateau.bad = state
        best_loss, best_state, start = saved["best_loss"], saved["best_state"], saved["iteration"]
    groups = optimizer.param_groups  # after loading: load_state_dict replaces the group dicts

    def save(iteration: int) -> None:
        store.save(label, dict(
            modules=[m.state_dict() for m in modules], optimizer=optimizer.state_dict(),
            plateaus=[(p.best, p.bad) for p in plateaus], best_loss=best_loss, best_state=best_state,
            iteration=iteration,
        ))

    def live() -> list[int]:
        return [b for b in range(count) if groups[b]["lr"] >= learning_rate * config.min_lr_ratio]

    bar = tqdm(total=iterations, initial=start, desc=label, disable=not progress, leave=False)
    # The bar sums over every module: its latest loss (a stopped module's last) beside its best,
    # so the two totals are of the same quantity and best <= loss.
    latest = list(best_loss)
    iteration = start
    while iteration < iterations and (active := live()):
        optimizer.zero_grad(set_to_none=True)  # modules that have stopped get no gradient: Adam skips them
        losses = torch.stack([sum(terms.values()) for terms in objective(active)])
        values = losses.detach().cpu().tolist()  # the iteration's one device-to-host copy
        for b, value in zip(active, values):
            if not np.isfinite(value):
                which = f" (scene {b})" if count > 1 else ""
                raise FloatingPointError(f"{label}{which}: the loss became {value} at iteration {iteration}")
        losses.sum().backward()
        lr_before = [group["lr"] for group in groups]
        for b, value in zip(active, values):
            latest[b] = value
            if value < best_loss[b]:
                best_loss[b], best_state[b] = value, copy_state(modules[b])
            # Warm-up: Adam's first steps move every parameter by about lr, whatever its gradient,
            # which can push the hand out of a grasp that only just holds.
            groups[b]["lr"] = lr_before[b] * min(1.0, (iteration + 1) / config.warmup_iterations)
        optimizer.step()
        for b, value in zip(active, values):
            groups[b]["lr"] = lr_before[b]
            if plateaus[b].step(value, groups[b]):
                # Back to the best parameters, and forget the momentum that led away from them.
                modules[b].load_state_dict(best_state[b])
                for parameter in modules[b].parameters():
                    optimizer.state.pop(parameter, None)
        iteration += 1
        for rung, margin in rungs if rivals is not None else ():
            if iteration == rung:
                for b in _behind_rivals(rivals, best_loss, margin):
                    groups[b]["lr"] = 0.0
        bar.update(1)
        bar.set_postfix(loss=f"{sum(latest):.4f}", best=f"{sum(best_loss):.4f}", lr=f"{groups[active[0]]['lr']:.1e}",
                        **({"running": f"{len(active)}/{count}"} if count > 1 else {}))
        if iteration % config.checkpoint_every == 0:
            save(iteration)
    bar.close()
    unrun = [b for b in range(count) if best_loss[b] == float("inf")]
    if unrun:  # no iteration ran: report the loss where the parameters are
        with torch.no_grad():
            for b, terms in zip(unrun, objective(unrun)):
                best_loss[b] = float(sum(terms.values()))
    for module, state in zip(modules, best_state):
        module.load_state_dict(state)
    save(iterations)
    return best_loss


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
    return {k: v.detach().clone() for k, v in module.state_dict().items()}
