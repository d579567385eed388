"""Process memory: keep freed memory for reuse instead of handing it back to the system."""
import ctypes
import ctypes.util

#: glibc mallopt parameters (malloc.h)
_M_TRIM_THRESHOLD = -1
_M_MMAP_MAX = -4


def keep_freed_memory():
    """Make glibc's malloc serve every block from its heap (no mmap) and never trim the heap,
    so that the N×N arrays a spectrum allocates and frees again at every assembly, LU and
    Newton step reuse pages already mapped instead of faulting fresh zeroed pages in.

    Measured on one deep pulse (L = 3.8 km, N = 3542/5009, one thread): 0.98 M minor
    page faults and 9.1 s of system time without, 0.26 M and 2.6 s with; the peak resident
    memory grows 10 % (2.86 → 3.16 GB; freed blocks stay with the process). A long-running
    process's malloc setting: called by the spectrum command and its workers, not on import.
    Returns whether it took effect (False off glibc)."""
    name = ctypes.util.find_library("c")
    try:
        libc = ctypes.CDLL(name)
        mallopt = libc.mallopt
    except (OSError, AttributeError, TypeError):
        return False
    mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
    mallopt.restype = ctypes.c_int
    ok = mallopt(_M_MMAP_MAX, 0) == 1
    # the largest int: the heap's top is never trimmed
    return ok and mallopt(_M_TRIM_THRESHOLD, 2**31 - 1) == 1
