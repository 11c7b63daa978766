"""The ``complete`` stage's library (DRAWER's amodal completion): what the capture cannot see,
and the scene cut into bodies.

``interiors`` (fitted interior templates behind every articulated front: drawer boxes moving
with their drawer, static cavities behind doors and flaps, oven-like appliance boxes; depths
measured on the mesh and fitted jointly; DRAWER's fixed-depth rule for comparison; the
interior colours), ``cut`` (each part's body and the static remainder with the cavity it
sweeps), ``rigid`` (closed solids of rigid objects), ``static_collision`` (the static scene as
boxes), ``io`` (the ``complete/`` folder), ``pipeline`` (the stage's work).
"""
