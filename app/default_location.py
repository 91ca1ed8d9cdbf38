"""The location every aircraft carries and today's requests name implicitly, without imports:
the offline command line reads it without loading the service's database layer."""

# created by migration 20261128_a7d4c2e9f5b3 with this id, so rows stored before locations
# point at it
DEFAULT_LOCATION_ID = 1
DEFAULT_LOCATION = "default"
