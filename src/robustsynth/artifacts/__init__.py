"""What robustsynth writes and reads: :mod:`.files` (atomic, deterministic output files) and
:mod:`.gains` (the gains file's format: writing, reading, its id and the controller description);
:mod:`.inputs` tells apart the files a command is given and keeps its new output directories."""
