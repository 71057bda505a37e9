"""What the controller acts on: :mod:`.kinematic` (the tracked robot of eq. 12 with its network
delivery, the interface the Monte Carlo and the adversary drive), :mod:`.path` (the path and its
error frames) and :mod:`.linear` (any linear plant, as a :class:`~robustsynth.core.plant.Plant`)."""
