"""What every plant shares: the network the commands cross (:mod:`robustsynth.core.network`)."""
