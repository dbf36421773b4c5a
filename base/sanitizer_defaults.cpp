// Default sanitizer settings, compiled into every dejag executable of a sanitizer build (ASan+UBSan or
// TSan), so tests, the CLI and the child processes tests start all run with them.
// Suppressed here: only third-party code dejag cannot fix.

extern "C" {

#if defined(DEJAG_SANITIZE_ADDRESS)
// Full stacks for leak reports, so the suppression below can match a frame inside OpenImageIO.
const char* __asan_default_options() {
    return "fast_unwind_on_malloc=0:detect_leaks=1";
}
// Quiet about the suppressions it used: a CLI error must stay one line even under ASan.
const char* __lsan_default_options() {
    return "print_suppressions=0";
}
const char* __ubsan_default_options() {
    return "print_stacktrace=1:halt_on_error=1";
}
// OpenImageIO 2.4's PNG reader longjmps out of libpng's read callback after copying the error message
// into a std::string that is never destroyed (31 bytes per failed read of a truncated PNG).
const char* __lsan_default_suppressions() {
    return "leak:OpenImageIO_v2_4::PNGInput::PngReadCallback\n";
}
#endif

#if defined(DEJAG_SANITIZE_THREAD)
const char* __tsan_default_options() {
    return "halt_on_error=1:print_suppressions=0";
}
// OpenImageIO and OpenEXR run their own thread pools inside uninstrumented shared libraries (e.g. when
// writing images); TSan cannot see their synchronisation and reports races between their own threads.
const char* __tsan_default_suppressions() {
    return "race:libOpenImageIO.so\n"
           "race:libOpenImageIO_Util.so\n"
           "race:libOpenEXR\n"
           "race:libIlmThread\n"
           "called_from_lib:libOpenImageIO.so.2.4\n"
           "called_from_lib:libOpenImageIO_Util.so.2.4\n";
}
#endif

}  // extern "C"
