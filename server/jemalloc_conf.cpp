// voxeld allocates with jemalloc (Debian's libjemalloc2) when built without sanitizers:
// evicted chunks must go back to the system, and glibc's malloc_trim, which does that,
// stalled the world pipeline up to 400 ms on a 1 GB heap (docs/PERFORMANCE.md, "Memory
// returned after eviction"). jemalloc's background thread returns unused pages about a
// second after they are freed, outside the pipeline thread. Read by jemalloc at start.
extern "C" {
// NOLINTNEXTLINE: the name jemalloc looks for.
const char* malloc_conf = "background_thread:true,dirty_decay_ms:1000,muzzy_decay_ms:0";
}
