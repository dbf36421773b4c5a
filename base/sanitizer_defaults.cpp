// Default sanitizer settings, compiled into every dejag executable of a sanitizer build (ASan+UBSan or
// TSan), so tests, the CLI and the child processes tests start all run with them.
// Suppressed here: only third-party code dejag cannot fix.

extern "C" {

#if defined(DEJAG_SANITIZE_ADDRESS)
// Leak detection on, with the fast default unwinder: the slow one (fast_unwind_on_malloc=0) deadlocks
// when llvmpipe's JIT registers its frames under libgcc's unwinder lock and allocates (seen under
// `dejag data generate`). OpenImageIO's known leak is left out where it happens (data/image.cpp).
const char* __asan_default_options() {
    return "detect_leaks=1";
}
// Quiet about the suppressions it used: a CLI error must stay one line even under ASan.
const char* __lsan_default_options() {
    return "print_suppressions=0";
}
const char* __ubsan_default_options() {
    return "print_stacktrace=1:halt_on_error=1";
}
// Mesa's OSMesa keeps a few small context objects (480 bytes) alive past the context's destruction; the
// window system under `dejag view` (GLFW, Xlib and XCB, Mesa's GLX and DRI drivers) keeps its own past
// exit, and Open MPI its own past MPI_Finalize. Matched by library name: the fast unwinder stops at the first frame inside the uninstrumented
// library.
const char* __lsan_default_suppressions() {
    return "leak:libOSMesa.so\n"
           "leak:libglfw.so\n"
           "leak:libX11.so\n"
           "leak:libxcb.so\n"
           "leak:libGLX_mesa.so\n"
           "leak:libGLdispatch.so\n"
           "leak:libGLX.so\n"
           "leak:swrast_dri.so\n"
           "leak:libgallium\n"
           "leak:libLLVM\n"
           // Open MPI (dejag-mpi) keeps its runtime's tables past MPI_Finalize, in itself, its plug-ins
           // (mca_*.so) and the libraries under it.
           "leak:libmpi.so\n"
           "leak:libopen-pal.so\n"
           "leak:libopen-rte.so\n"
           "leak:mca_\n"
           "leak:libhwloc.so\n"
           "leak:libpmix.so\n"
           "leak:libevent\n";
}
#endif

#if defined(DEJAG_SANITIZE_THREAD)
const char* __tsan_default_options() {
    return "halt_on_error=1:print_suppressions=0";
}
// OpenImageIO and OpenEXR run their own thread pools inside uninstrumented shared libraries (e.g. when
// writing images), and so does Mesa's llvmpipe behind OSMesa (its rasteriser threads, whose mutexes it
// destroys at context teardown); TSan cannot see their synchronisation and reports races between
// their own threads.
// OpenEXR takes a file's stream mutex in ScanLineInputFile::readPixels, and TSan sees the lock but not
// its release inside the uninstrumented library: each thread's list of "held" locks grows by one per
// EXR read until TSan's deadlock detector aborts at 64 (CHECK in sanitizer_deadlock_detector.h, exit 66),
// after reporting every later lock as an inversion. TSan ignores the interceptors called from OpenEXR,
// as it already does for OpenImageIO's.
const char* __tsan_default_suppressions() {
    return "race:libOSMesa.so\n"
           "race:libOpenImageIO.so\n"
           "race:libOpenImageIO_Util.so\n"
           "race:libOpenEXR\n"
           "race:libIlmThread\n"
           "called_from_lib:libOpenImageIO.so.2.4\n"
           "called_from_lib:libOpenImageIO_Util.so.2.4\n"
           "called_from_lib:libOpenEXR-3_1.so.30\n";
}
#endif

}  // extern "C"
