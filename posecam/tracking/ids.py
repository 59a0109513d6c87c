"""People's ids: a video's frames held back until the tracks in them are confirmed, then numbered."""

from __future__ import annotations

from collections import deque
from typing import Generic, TypeVar

from posecam.results import Dropped, Frame
from posecam.tracking.track import Track
from posecam.tracking.tracker import Tracker

Item = TypeVar("Item")


def number_people(frame: Frame, tracks: list[Track]) -> None:
    """Give the people of `frame` (one a track of `tracks`, in order) their tracks' ids; a
    person whose track is not confirmed moves to `frame.dropped` ("unconfirmed")."""
    people = []
    for person, track in zip(frame.people, tracks):
        if track.number is None:
            frame.dropped.append(Dropped("unconfirmed", person.score, person.bbox))
        else:
            person.id = track.number
            people.append(person)
    frame.people = people


class ConfirmedIds(Generic[Item]):
    """Frames held back until the tracks in them are decided, so that ids are numbered only
    for confirmed tracks (a false start or half a person takes no id). A frame comes out when
    each of its tracks is confirmed or forgotten (a false start), or when it has waited
    `confirm_frames` frames; then its people take their ids (`number_people`), the ones still
    unconfirmed go to its `dropped`. Each frame travels with an item of the caller's (the frame
    itself, or the frame and its image), given back in order."""

    def __init__(self, tracker: Tracker):
        self.tracker = tracker
        self._held: deque[tuple[Frame, list[Track], Item]] = deque()

    def push(self, frame: Frame, tracks: list[Track], item: Item) -> list[Item]:
        """Hold `frame` (its people one a track of `tracks`); returns the items now decided."""
        self._held.append((frame, tracks, item))
        return self._release(final=False)

    def flush(self) -> list[Item]:
        """The items still held, at the end of the video (where the people still followed are
        confirmed: the video's end, not a miss, cut their confirmation short)."""
        self.tracker.confirm_followed()
        return self._release(final=True)

    def _release(self, final: bool) -> list[Item]:
        out = []
        while self._held:
            frame, tracks, item = self._held[0]
            alive = {id(t) for t in self.tracker.tracks}
            waiting = any(t.number is None and id(t) in alive for t in tracks)
            if waiting and not final and len(self._held) <= self.tracker.policy.confirm_frames:
                break
            self._held.popleft()
            number_people(frame, tracks)
            out.append(item)
        return out
