"""What every plant shares: the network the commands cross and every delay / loss sequence on it
(:mod:`.network`), the lifted model under time-varying delay (:mod:`.lifting`) and any linear plant's exact
lifted map with its guaranteed over-approximation (:mod:`.delays`), what the core asks of a plant
(:mod:`.plant`: the ``Plant`` protocol) and the conformance suite every plant passes (:mod:`.conformance`:
``check_plant``)."""
