"""Video -> posed frames: frame reading and selection, pycolmap SfM, similarity alignment."""
