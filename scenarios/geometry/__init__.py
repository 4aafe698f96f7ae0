"""arfem.scenarios.geometry."""
