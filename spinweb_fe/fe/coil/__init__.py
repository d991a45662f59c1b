"""The stowed coil: its levels and their release, bundles, and the payout devices at the departure points."""
