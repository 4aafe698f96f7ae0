"""arfem.scenarios.diagnosis."""
