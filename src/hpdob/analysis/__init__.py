"""Analysis of observers and of the linear closed loop.

estimation_transfer, estimation_response
    Closed-form disturbance-estimation response (the "Q-filter") of an observer.
closed_loop, closed_loop_poles, gang_of_four, loop_transfer, loop_margins
    The linear sampled-data loop as a python-control system, its poles, sensitivities, margins.
spectral_radii
    Closed-loop spectral radii over true plants and actuator delays (one loop checked once).
noise_gains, observer_noise_gain, noise_tradeoff
    Exact noise gains (discrete Lyapunov equation) and the accuracy/noise trade-off.
robust_stability_map
    Closed-loop stability over inertia or friction errors and observer bandwidths.
contact_stability_map, ContactStabilityMap, force_response, ForceResponse
    The force loop in contact: stability over environment stiffness or J_n/J and bandwidth;
    tau_env/tau_ref, its poles, zeros and -3 dB bandwidth.
contact_limit_cycle, ContactLimitCycle, relay_df, tanh_friction_df, quantiser_df, saturation_df
    The force loop in contact with its friction, quantiser and torque limit as describing
    functions: stable, limit cycle (its amplitude) or unstable.
compare_observers, Comparison
    The paper's observers, their position-only versions, ESO and Kalman at equal noise.
bode_figure, noise_figure
    The figures of docs/analysis.md: estimation response and noise gains against bandwidth.
"""

from ._closed_loop import RadiiScan as RadiiScan
from ._closed_loop import closed_loop, closed_loop_poles, spectral_radii
from ._comparison import DEFAULT_NOISE_GAIN as DEFAULT_NOISE_GAIN
from ._comparison import Comparison, compare_observers
from ._contact_map import ContactStabilityMap, contact_stability_map
from ._describing import (
    ContactLimitCycle,
    contact_limit_cycle,
    quantiser_df,
    relay_df,
    saturation_df,
    tanh_friction_df,
)
from ._estimation import estimation_response, estimation_transfer
from ._figures import bode_figure, noise_figure
from ._force_response import ForceResponse, force_response
from ._linear_loop import MAX_DELAY_SAMPLES as MAX_DELAY_SAMPLES
from ._noise import NoiseGains, noise_gains, observer_noise_gain
from ._noise import channel_noise_gains as channel_noise_gains
from ._robust import StabilityMap, robust_stability_map
from ._sensitivity import GangOfFour, LoopMargins, gang_of_four, loop_margins, loop_transfer
from ._tradeoff import NoiseTradeoff, noise_tradeoff

# Names imported "as" themselves and absent from __all__ are hpdob-internal: for the other
# subpackages, not part of the public API (docs/architecture.md, "Dependency order").
__all__ = [
    "Comparison",
    "ContactLimitCycle",
    "ContactStabilityMap",
    "ForceResponse",
    "GangOfFour",
    "LoopMargins",
    "NoiseGains",
    "NoiseTradeoff",
    "StabilityMap",
    "bode_figure",
    "closed_loop",
    "closed_loop_poles",
    "compare_observers",
    "contact_limit_cycle",
    "contact_stability_map",
    "estimation_response",
    "estimation_transfer",
    "force_response",
    "gang_of_four",
    "loop_margins",
    "loop_transfer",
    "noise_figure",
    "noise_gains",
    "noise_tradeoff",
    "observer_noise_gain",
    "quantiser_df",
    "relay_df",
    "robust_stability_map",
    "saturation_df",
    "spectral_radii",
    "tanh_friction_df",
]
