"""Lab Streaming Layer: the study on the lab's clock (DESIGN.md, "The lab's clock").

Outlets for the study's events and the robot's state (:mod:`.outlets`), the lab's streams
recorded into the study database (:mod:`.recorder`), LabRecorder's XDF files imported and
aligned with the trials (:mod:`.xdf`). pylsl and pyxdf are an extra (``pip install -e
'.[lsl]'``), imported only when a session, an export or an import uses them
(:mod:`.runtime`); the protocol's ``[lsl]`` table is plain data (:mod:`.settings`).
"""
