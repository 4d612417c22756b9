"""Products on disk: drive.h5, trajectory.h5 and the images, written atomically and checked by their checksums."""
