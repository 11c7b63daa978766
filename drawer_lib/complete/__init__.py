"""The ``complete`` stage's library (DRAWER §5, amodal completion): what the capture cannot see.

Among its modules: ``interiors`` (fitted interior templates behind every articulated front:
drawer boxes moving with their drawer, static cavities behind doors and flaps, oven-like
appliance boxes; depths measured on the mesh and fitted jointly; DRAWER's fixed-depth rule for
comparison; the observed-colour texturer) with its config in ``interiors_config``.
"""
