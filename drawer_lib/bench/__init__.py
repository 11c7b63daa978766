"""The articulation benchmark as stages of the pipeline: procedural kitchens of a train split
(the decision weights are fitted on it) and a test split (never tuned on), built as the
pipeline builds a scene (:mod:`~drawer_lib.bench.kitchens`), the fit of the decision weights
(:mod:`~drawer_lib.bench.fit`) and each split's scores and table
(:mod:`~drawer_lib.bench.evaluate`). The splits: :mod:`drawer_lib.synth.splits`."""
