"""arfem.scenarios.compensation."""
