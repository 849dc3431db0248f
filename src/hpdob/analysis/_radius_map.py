"""What the spectral-radius maps share: the grid's stability and its long-format table."""

from __future__ import annotations

import numpy as np

from .._table import CsvTable, columns_to_pandas

__all__ = ["_RadiusMap"]


class _RadiusMap(CsvTable):
    """The base of :class:`~hpdob.StabilityMap` and :class:`~hpdob.analysis.ContactStabilityMap`: a
    ``spectral_radius`` array over ``values`` x ``bandwidths`` and its table, one row per grid
    point, whose columns the subclass's ``_columns`` gives (``to_csv``: :class:`CsvTable`)."""

    __slots__ = ()
    spectral_radius: np.ndarray

    @property
    def stable(self) -> np.ndarray:
        """Boolean array: ``spectral_radius < 1``."""
        return self.spectral_radius < 1.0

    def to_pandas(self):
        """The map in long format.

        Returns
        -------
        pandas.DataFrame
            One row per grid point: the varied parameter, ``bandwidth_rad_s``, the fixed
            parameters (``order`` too for a :class:`~hpdob.StabilityMap`),
            ``delay_samples``, ``spectral_radius`` and ``stable``. A
            :class:`~hpdob.analysis.ContactStabilityMap` with ``bandwidth_of="dob"`` or
            ``"reaction"`` has ``dob_bandwidth_rad_s`` and ``reaction_bandwidth_rad_s``
            instead of ``bandwidth_rad_s``, the varied one first.

        Raises
        ------
        ImportError
            If pandas is not installed (``pip install hpdob[pandas]``).
        """
        return columns_to_pandas(self._columns())
