// Linked into every fuzz target: undefined behaviour stops the run like a crash, so
// libFuzzer keeps the input, also when a target is started by hand without UBSAN_OPTIONS
// (the libraries are built with the recoverable checks of -DVOXEL_SANITIZE).
extern "C" const char* __ubsan_default_options() { return "halt_on_error=1:print_stacktrace=1"; }
