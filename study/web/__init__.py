"""The study server for browser participants and the experimenter's live view (issue 37;
DESIGN.md, "Participants in a browser"): ``asa serve`` runs each participant's session in
a process of its own (:mod:`.session_proc`) with a :class:`.participant.WebParticipant`,
which speaks to the page through the server (:mod:`.server`, :mod:`.relay`) in the
messages of :mod:`.messages`; the page (``static/``) draws the screens that
:mod:`study.ui.describe` describes. Nothing is imported here, so that the protocol's
settings (:mod:`.settings`) load without aiohttp.
"""
