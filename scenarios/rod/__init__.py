"""arfem.scenarios.rod."""
