"""Errors the predictor reports to an operator: each one says what is wrong and what to do."""


class PredictorError(Exception):
    """Base of every predictor error meant for an operator (printed as one line, no traceback)."""


class WeatherError(PredictorError):
    """The weather files cannot answer the question (missing, corrupt, out of range)."""


class TerrainError(PredictorError):
    """A terrain source is unreadable or malformed."""


class OutOfCoverageError(WeatherError):
    """A descent path or release point leaves the region or time span the weather covers."""


class UsageError(PredictorError):
    """A command line argparse accepted but that cannot mean anything (options that exclude each other,
    a count out of range): exit status 2 like argparse's own, so a script can tell a typo from a failure."""


class WeatherFileError(WeatherError):
    """One weather file is unusable: damaged, hostile, or it made the GRIB decoder fail or die.

    The one type a caller that serves others (``drs serve predictor``, the console) catches to refuse the
    file and keep running; ``path`` is the file, ``fault`` what is wrong with it, ``str()`` both in one line.
    """

    def __init__(self, path: object, fault: str, said: str | None = None) -> None:
        """``said``: the whole line when a reader already worded it with the file's name in it."""
        self.path = str(path)
        self.fault = " ".join(fault.split())
        super().__init__(" ".join(said.split()) if said else f"{self.path}: {self.fault}")
