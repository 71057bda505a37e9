from robustsynth.cli import entry

entry()
