"""Watching runs: evaluation of a checkpoint, Rerun recordings, videos."""
