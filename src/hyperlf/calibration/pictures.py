"""Pictures of a calibration for users: detected corners, registered views, residuals."""

from __future__ import annotations

__all__ = ["save_corner_pictures", "save_registration_picture", "save_residual_picture"]


def save_corner_pictures(*args, **kwargs):  # filled in below
    raise NotImplementedError


def save_registration_picture(*args, **kwargs):
    raise NotImplementedError


def save_residual_picture(*args, **kwargs):
    raise NotImplementedError
