"""Back ends: everything written from the IR: components, diagrams, the model as YAML or XML,
the IR as text, and the structure a component tells its observers."""
