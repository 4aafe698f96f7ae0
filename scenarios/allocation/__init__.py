"""arfem.scenarios.allocation."""
