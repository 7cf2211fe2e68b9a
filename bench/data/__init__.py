"""Layer 2: point cloud files, sequences, data sources and the embedded stand-ins, output folder guards. Imports core."""
