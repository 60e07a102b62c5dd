"""Learning-rate schedule: constant, then linear decay, then constant (paper section 4.4)."""

from __future__ import annotations


def lr_at(step: int, total: int, lr: float, lr_end: float, decay_start: float, decay_end: float) -> float:
    """Learning rate for optimizer step ``step`` (0-based) of ``total``: ``lr`` until
    ``decay_start * total``, linear to ``lr_end`` at ``decay_end * total``, ``lr_end`` after."""
    a = decay_start * total
    b = decay_end * total
    if step <= a:
        return lr
    if step >= b:
        return lr_end
    t = (step - a) / (b - a)
    return lr + (lr_end - lr) * t


def lr_factor(step: int, total: int, lr: float, lr_end: float, decay_start: float, decay_end: float) -> float:
    """``lr_at`` relative to ``lr`` (what torch's LambdaLR multiplies the base rate by)."""
    return lr_at(step, total, lr, lr_end, decay_start, decay_end) / lr
