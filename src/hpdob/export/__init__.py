"""Deployment: an observer as dependency-free C99 for a microcontroller, or as an FMU.

export_c, render_c
    Write (or return the text of) ``<prefix>.h`` and ``<prefix>.c`` (double, float, or fixed
    point with ``dtype="q31"``).
fixed_point_design, FixedPointDesign, FixedPointObserver, fixed_point_error_bound
    Q formats and integer tables from declared ranges, the bit-exact Python model of the
    fixed-point C, and its error bound against the exact observer.
"""

from ._c import DTYPES as DTYPES
from ._c import check_directory as check_directory
from ._c import check_prefix as check_prefix
from ._c import export_c, render_c
from ._fixed import FixedPointDesign, fixed_point_design
from ._fixed_runtime import FixedPointObserver, fixed_point_error_bound
from ._fixed_tables import FixedPointRow
from ._fmu import FMUBuildError, export_fmu

# Names imported "as" themselves and absent from __all__ are hpdob-internal: for the other
# subpackages, not part of the public API (docs/architecture.md, "Dependency order").
__all__ = [
    "FMUBuildError",
    "FixedPointDesign",
    "FixedPointObserver",
    "FixedPointRow",
    "export_c",
    "export_fmu",
    "fixed_point_design",
    "fixed_point_error_bound",
    "render_c",
]
