"""Fleet mode: many vessel-runs fitted on Dask distributed workers (``python -m diffship.fleet``)."""

from .manifest import FleetJob, read_manifest

__all__ = ["FleetJob", "read_manifest"]
