"""``hfsmc lsp``: a Language Server Protocol server for model files (SPEC 8.2,
docs/editors.md).  ``analysis.py`` holds what the server knows of one document,
``features.py`` answers the requests from it, ``server.py`` speaks the protocol
(pygls) on stdio."""
