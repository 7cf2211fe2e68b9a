"""Layer 5: the results store, comparisons with baselines, costs, statistics, oracle fills. Imports the layers below."""
