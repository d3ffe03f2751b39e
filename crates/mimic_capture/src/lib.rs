//! Frame sources for mimic: the v1 recording format, importers of other trackers' files, paced replay.
