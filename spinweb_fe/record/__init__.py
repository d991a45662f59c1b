"""Recording a run: history columns, the energy balance, arm measures and the recorder protocol."""
