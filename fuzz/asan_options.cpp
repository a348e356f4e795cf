// ASan defaults of every fuzz target: a failed C allocation returns NULL, as malloc does outside
// ASan, so CFITSIO's own handling of a header that asks for petabytes (a MEMORY_ALLOCATION status,
// hence a FitsError) is what is tested; a failed C++ `new` still aborts, and is a finding.
extern "C" const char* __asan_default_options() { return "allocator_may_return_null=1"; }
