"""arfem.scenarios.commands."""
