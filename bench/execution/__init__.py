"""Layer 4: running experiments: run folders, workers, executors, the runner, run claims. Imports the layers below."""
