"""Templates and runtime modules of the generated Python component (a data package)."""
