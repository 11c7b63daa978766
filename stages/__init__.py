"""One thin entry point per DVC stage: read config, call drawer_lib, write outputs."""
