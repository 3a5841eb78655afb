"""Code that only a command uses: ``convert``, ``view`` and shell completion.

The pipeline's stages (front end, IR builder, checks, emitters) never import
from here; ``hfsmc/cli.py`` does (the layers are listed in pyproject.toml,
``[tool.importlinter]``).
"""
