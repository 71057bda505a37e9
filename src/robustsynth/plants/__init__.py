"""What the controller acts on: :mod:`.kinematic` (the tracked robot of eq. 12 with its network
delivery, the interface the Monte Carlo and the adversary drive) and :mod:`.path` (the path and its
error frames)."""
