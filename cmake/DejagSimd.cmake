# Runtime-dispatched SIMD kernels.
#
# dejag_add_simd_kernels(TARGET SOURCES...) compiles each kernel source three times, once per SIMD level,
# into the namespaces dejag::simd_scalar, dejag::simd_avx2 and dejag::simd_avx512 (the macro
# DEJAG_SIMD_NAMESPACE names the one being compiled). base/simd.h picks the level at run time from the CPU
# and the DEJAG_SIMD environment variable, so one binary runs everywhere and tests can force each path.
set(DEJAG_SIMD_FLAGS_scalar -fno-tree-vectorize -fno-tree-slp-vectorize -ffp-contract=off)
set(DEJAG_SIMD_FLAGS_avx2 -mavx2 -mfma -mf16c -ffp-contract=fast)
# -mavx512bf16 only makes the bf16 intrinsics available (GCC 12 never emits them for plain code); they
# run only where bf16Available() says the CPU has them (nn/fast_conv_kernels.cpp).
set(DEJAG_SIMD_FLAGS_avx512 -mavx512f -mavx512bw -mavx512dq -mavx512vl -mavx512bf16 -mavx2 -mfma -mf16c
                            -mprefer-vector-width=512 -ffp-contract=fast)

function(dejag_add_simd_kernels target)
    foreach(level scalar avx2 avx512)
        set(lib ${target}_simd_${level})
        add_library(${lib} OBJECT ${ARGN})
        target_compile_definitions(${lib} PRIVATE DEJAG_SIMD_NAMESPACE=simd_${level}
                                                  DEJAG_SIMD_LEVEL_${level}=1)
        target_compile_options(${lib} PRIVATE ${DEJAG_SIMD_FLAGS_${level}})
        target_include_directories(${lib} PRIVATE ${PROJECT_SOURCE_DIR})
        target_link_libraries(${lib} PRIVATE dejag_warnings)
        set_target_properties(${lib} PROPERTIES POSITION_INDEPENDENT_CODE ON)
        target_sources(${target} PRIVATE $<TARGET_OBJECTS:${lib}>)
    endforeach()
endfunction()
