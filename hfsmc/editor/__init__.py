"""``hfsmc edit MODEL``: the model in a browser page, edited through the edit engine
(docs/editor.md).

``model.py`` turns an edit session into what the page draws (the structure, the
diagnostics keyed by element, the layout), ``server.py`` serves the page and its one
WebSocket with the web view's trust rules (hfsmc/web/trust.py)."""
