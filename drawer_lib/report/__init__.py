"""Human-readable views of the pipeline's outputs (contact sheets, tables, dashboards)."""
