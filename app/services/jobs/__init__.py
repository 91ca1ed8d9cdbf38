"""The work the worker does and its queue: retrains (their gate, a location's analysis version,
activation, cancelling) and the forecast batch."""
