"""The rigid hub's phases: on a fixed axis, as a free body, its rigid-body algebra and the cable-hub contact."""
