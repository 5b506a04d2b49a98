"""Reproducible file headers: the time from ``SOURCE_DATE_EPOCH``, no user name.

Build systems that want the same bytes from the same input set ``SOURCE_DATE_EPOCH`` (seconds
since 1970, UTC; reproducible-builds.org).  Where it is set, the STEP header's FILE_NAME time
stamp and the IGES global section's dates are that time; where it is not, OpenCASCADE's
current time stays.  The IGES author field, which OpenCASCADE fills with the login name, is
always left empty: a delivered file should not carry who ran the build.
"""

from __future__ import annotations

import datetime as _dt
import os

from patching.errors import NupatchError

__all__ = ["source_date", "step_time_stamp", "iges_date", "apply_to_iges", "apply_to_step_header"]


def source_date() -> _dt.datetime | None:
    """The UTC time ``SOURCE_DATE_EPOCH`` names, None if unset; NupatchError if not an integer."""
    text = os.environ.get("SOURCE_DATE_EPOCH")
    if text is None or text == "":
        return None
    try:
        seconds = int(text)
        return _dt.datetime.fromtimestamp(seconds, tz=_dt.timezone.utc)
    except (ValueError, OverflowError, OSError):
        raise NupatchError(f"SOURCE_DATE_EPOCH must be whole seconds since 1970, not {text!r}", "environment") from None


def step_time_stamp() -> str | None:
    """ISO 8601 time stamp for STEP's FILE_NAME, or None (keep OCC's)."""
    when = source_date()
    return None if when is None else when.strftime("%Y-%m-%dT%H:%M:%S")


def iges_date() -> str | None:
    """IGES global-section date YYYYMMDD.HHNNSS, or None (keep OCC's)."""
    when = source_date()
    return None if when is None else when.strftime("%Y%m%d.%H%M%S")


def apply_to_step_header(header) -> None:
    """Set an ``APIHeaderSection_MakeHeader``'s time stamp from SOURCE_DATE_EPOCH (if set)."""
    from OCP.TCollection import TCollection_HAsciiString

    stamp = step_time_stamp()
    if stamp is not None:
        header.SetTimeStamp(TCollection_HAsciiString(stamp))


def apply_to_iges(writer) -> None:
    """Empty author, and the dates from SOURCE_DATE_EPOCH (if set), in an IGESControl_Writer's
    model (after ``ComputeModel``, before ``Write``)."""
    from OCP.TCollection import TCollection_HAsciiString

    model = writer.Model()
    section = model.GlobalSection()
    section.SetAuthorName(TCollection_HAsciiString(""))
    date = iges_date()
    if date is not None:
        section.SetDate(TCollection_HAsciiString(date))
        section.SetLastChangeDate(TCollection_HAsciiString(date))
    model.SetGlobalSection(section)
