"""Layer 1 (lowest): errors, atomic writes, canonical JSON, parameters, progress bars, instruction-set pins, the paper's facts. Imports no other bench layer."""
