"""Running a case: the event loop, the driver that writes a result folder, restarts and the terminal."""
