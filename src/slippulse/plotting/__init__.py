"""plotting: figures, one module per layer drawn — steady pulses and the paper's figures, the
stability spectrum, perturbation scans and verification runs (matplotlib, Agg, no screen needed)."""
