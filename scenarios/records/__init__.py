"""arfem.scenarios.records."""
