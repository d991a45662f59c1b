"""Exceptions that the command line turns into exit codes (see docs/interface.md)."""


class InputError(Exception):
    """Invalid user input: case file, argument or mesh. The CLI exits with code 2.

    Parameters
    ----------
    source : str
        The file (or argument) at fault.
    key : str
        Dotted key inside the source, or '' when the whole source is at fault.
    reason : str
        What is wrong, in one line.
    """

    def __init__(self, source, key, reason):
        self.source = str(source)
        self.key = key
        self.reason = reason
        where = f"{self.source}: {key}" if key else self.source
        super().__init__(f"{where}: {reason}")


class RunError(Exception):
    """A run-time failure (instability, I/O). The CLI exits with code 1.

    Parameters
    ----------
    time : float or None
        Simulated time [s] at which the run stopped.
    cause : str
        What happened.
    """

    def __init__(self, cause, time=None):
        self.time = time
        self.cause = cause
        msg = cause if time is None else f"stopped at t = {time:.6g} s: {cause}"
        super().__init__(msg)


class RunInterrupted(RunError):
    """A run stopped cleanly by a signal at an event boundary (CLI exit code 1).

    Parameters
    ----------
    signame : str
        'SIGINT' or 'SIGTERM'.
    time : float [s] or None
        Simulated time of the stop (None: before the run started).
    when : str
        Where it stopped when there is no time, e.g. 'during set-up'.
    """

    def __init__(self, signame, time, when=""):
        super().__init__(f"interrupted by {signame}", time=time)
        self.signame = signame
        self.when = when

    def __str__(self):
        if self.time is None:
            return " ".join(filter(None, (f"interrupted by {self.signame}", self.when)))
        return f"interrupted by {self.signame} at t = {self.time:.6g} s"
