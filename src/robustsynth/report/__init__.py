"""Output files: atomic writes, JSON/MAT/Markdown renderers (:mod:`.artifacts`, :mod:`.markdown`),
and figures (:mod:`.plots`, the only module that imports matplotlib)."""
