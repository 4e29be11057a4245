"""Speed and memory benchmarks, each run side by side with a named peer (see docs/benchmarks.md)."""
