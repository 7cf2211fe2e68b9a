"""Layer 3: experiment configs and run specs, run records. Imports core and data."""
