"""arfem.scenarios.live.jsonl."""
