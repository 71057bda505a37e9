"""Output: JSON/MAT/Markdown renderers (:mod:`.markdown` and the stage modules), figures (:mod:`.plots`, the
only module that imports matplotlib), and the console: the summary lines each command prints (:mod:`.console`)
and the live feedback while it works (:mod:`.progress`)."""
