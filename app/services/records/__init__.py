"""What is recorded: aircraft, the location catalogue, flights and inspections (ingested, checked,
corrected, read back as histories).  A write keeps the forecast cache in step (app.services.
forecasts.forecast_cache) and compares a new inspection with its forecast (assessment)."""
