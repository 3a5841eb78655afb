"""Back ends: code, diagrams and model files written from the IR."""
