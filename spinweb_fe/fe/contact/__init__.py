"""Cable-cable contact and the crossing test: the exact continuous test, its broad phase, the penalty, the fail-safe's impulses and impact zones, and what the step loop does with them."""
