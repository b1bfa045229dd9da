"""Why a line stopped: one code per line, stored with the line."""

from enum import IntEnum


class Reason(IntEnum):
    OUT_OF_DOMAIN = 0   # last vertex lies on the domain boundary
    MAX_LENGTH = 1      # arc length reached exactly
    MAX_TIME = 2        # integration time reached exactly
    MAX_STEPS = 3       # step budget spent
    STAGNATION = 4      # speed fell below the stagnation threshold
    STEP_UNDERFLOW = 5  # step size fell below the minimum step
    NAN_FIELD = 6       # the line ran into a cell with NaN/inf nodes
    SEED_OUTSIDE = 7    # seed outside the domain or in a NaN cell
    LEFT_TIME_RANGE = 8  # pathlines: left the time range covered by the snapshots
    TOO_CLOSE = 9       # evenly spaced seeding: came within the test distance of another line

    @property
    def label(self) -> str:
        return self.name.lower()


REASON_NAMES = [r.label for r in Reason]
