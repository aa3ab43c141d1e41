"""The progress bar Model(..., progress=True) shows on stderr."""

import sys
import time


class ProgressBar:
    """Callable taking the fraction done; redraws one line of stderr at most every 0.1 s."""

    def __init__(self, stream=None, width=40, label="building cfl.Model"):
        self.stream = stream if stream is not None else sys.stderr
        self.width = width
        self.label = label
        self.start = time.monotonic()
        self.last_draw = -1.0
        # Carriage returns only redraw a terminal; a log file gets the final line alone.
        isatty = getattr(self.stream, "isatty", None)
        self.interactive = bool(isatty and isatty())

    def __call__(self, fraction):
        now = time.monotonic()
        done = fraction >= 1.0
        # Redrawing on every report would cost more than the build step it reports on a fast terminal.
        if not done and (not self.interactive or now - self.last_draw < 0.1):
            return
        self.last_draw = now
        filled = int(round(self.width * min(max(fraction, 0.0), 1.0)))
        bar = "#" * filled + "-" * (self.width - filled)
        start_of_line = "\r" if self.interactive else ""
        self.stream.write(f"{start_of_line}{self.label} [{bar}] {100 * fraction:5.1f}% {now - self.start:6.1f} s")
        if done:
            self.stream.write("\n")
        self.stream.flush()
