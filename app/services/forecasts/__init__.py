"""Where each tail stands and where it is going: the forecast cache (its rows, filled and
advanced), the sampled risk, one tail's forecast, an aircraft's answer and their reports."""
