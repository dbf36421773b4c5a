# Warnings for every dejag target; -Werror when DEJAG_WERROR is on (CI), sanitizers when asked.
add_library(dejag_warnings INTERFACE)
target_compile_options(dejag_warnings INTERFACE -Wall -Wextra -Wpedantic -Wshadow -Wnon-virtual-dtor
                                                -Wcast-align -Woverloaded-virtual -Wimplicit-fallthrough)
# GCC 12 at -O3 reports false -Wrestrict overlaps inside std::string concatenation (GCC bugs 105329,
# 105651); it fires on ordinary "literal" + std::string code, so it is off rather than worked around.
if(CMAKE_CXX_COMPILER_ID STREQUAL "GNU" AND CMAKE_CXX_COMPILER_VERSION VERSION_LESS 13)
    target_compile_options(dejag_warnings INTERFACE -Wno-restrict)
endif()
if(DEJAG_WERROR)
    target_compile_options(dejag_warnings INTERFACE -Werror)
endif()

if(DEJAG_SANITIZE STREQUAL "address")
    add_compile_options(-fsanitize=address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=undefined)
    add_link_options(-fsanitize=address,undefined)
elseif(DEJAG_SANITIZE STREQUAL "thread")
    add_compile_options(-fsanitize=thread -fno-omit-frame-pointer)
    add_link_options(-fsanitize=thread)
elseif(NOT DEJAG_SANITIZE STREQUAL "")
    message(FATAL_ERROR "DEJAG_SANITIZE must be '', 'address' or 'thread', not '${DEJAG_SANITIZE}'")
endif()

# Fuzzing: every library gets libFuzzer's coverage instrumentation (the targets link the fuzzer itself).
if(DEJAG_FUZZ)
    if(NOT CMAKE_CXX_COMPILER_ID STREQUAL "Clang")
        message(FATAL_ERROR "DEJAG_FUZZ needs Clang (libFuzzer): configure with the fuzz preset")
    endif()
    add_compile_options(-fsanitize=fuzzer-no-link)
    # libFuzzer's own reports (out-of-memory, timeout) go to stderr: nothing may silence it.
    add_compile_definitions(DEJAG_FUZZING=1)
endif()

# Sanitizer builds: every executable gets base/sanitizer_defaults.cpp (default options, suppressions).
function(dejag_add_sanitizer_defaults target)
    if(DEJAG_SANITIZE STREQUAL "address")
        target_sources(${target} PRIVATE ${PROJECT_SOURCE_DIR}/base/sanitizer_defaults.cpp)
        target_compile_definitions(${target} PRIVATE DEJAG_SANITIZE_ADDRESS=1)
    elseif(DEJAG_SANITIZE STREQUAL "thread")
        target_sources(${target} PRIVATE ${PROJECT_SOURCE_DIR}/base/sanitizer_defaults.cpp)
        target_compile_definitions(${target} PRIVATE DEJAG_SANITIZE_THREAD=1)
    endif()
endfunction()
