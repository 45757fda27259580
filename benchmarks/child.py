"""What the benchmarks' child processes share: code that reads the process's own peak resident
memory. Peak RSS is read from ``/proc/self/status`` (VmHWM), which belongs to this process image
alone; ``getrusage``'s ``ru_maxrss`` would also count the parent's memory at fork time."""

PEAK_RSS = """
def peak_rss_mib():
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024
"""
