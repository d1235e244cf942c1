# Small helpers shared by every folder of the project.

# Adds every direct subfolder of DIR that holds a CMakeLists.txt.
function(lookup_add_subdirectories dir)
    file(GLOB children RELATIVE ${CMAKE_CURRENT_SOURCE_DIR}/${dir}
         ${CMAKE_CURRENT_SOURCE_DIR}/${dir}/*/CMakeLists.txt)
    list(SORT children)
    foreach(child ${children})
        get_filename_component(sub ${child} DIRECTORY)
        add_subdirectory(${dir}/${sub})
    endforeach()
endfunction()

# lookup_add_library(NAME <stage> SOURCES ... PUBLIC_DEPS ... PRIVATE_DEPS ... [TESTING])
# Creates target lookup_<stage> (alias lookup::<stage>) with public headers in include/.
# TESTING: a fixture library for tests and benchmarks, neither installed nor exported.
function(lookup_add_library)
    cmake_parse_arguments(ARG "TESTING" "NAME" "SOURCES;PUBLIC_DEPS;PRIVATE_DEPS" ${ARGN})
    set(target lookup_${ARG_NAME})
    add_library(${target} ${ARG_SOURCES})
    add_library(lookup::${ARG_NAME} ALIAS ${target})
    target_include_directories(${target} PUBLIC
        $<BUILD_INTERFACE:${CMAKE_CURRENT_SOURCE_DIR}/include>
        $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>)
    target_link_libraries(${target} PUBLIC ${ARG_PUBLIC_DEPS} PRIVATE ${ARG_PRIVATE_DEPS})
    set_target_properties(${target} PROPERTIES EXPORT_NAME ${ARG_NAME})
    if(ARG_TESTING)
        return()
    endif()
    install(TARGETS ${target} EXPORT lookupTargets
            LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
            ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR})
    # include/lookup/<stage>/testing/ holds the headers of a TESTING library beside it.
    install(DIRECTORY include/ DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}
            PATTERN testing EXCLUDE)
endfunction()

# lookup_add_executable(NAME <program> SOURCES ... DEPS ...)
# Installed to bin/ with a run path relative to the binary (LOOKUP_INSTALL_RPATH), so the
# installed tree works from any prefix and after being moved; the program is added to the
# global property LOOKUP_PROGRAMS (the install tests run each one's --help).
function(lookup_add_executable)
    cmake_parse_arguments(ARG "" "NAME" "SOURCES;DEPS" ${ARGN})
    add_executable(${ARG_NAME} ${ARG_SOURCES})
    target_link_libraries(${ARG_NAME} PRIVATE ${ARG_DEPS})
    set_target_properties(${ARG_NAME} PROPERTIES INSTALL_RPATH "${LOOKUP_INSTALL_RPATH}")
    install(TARGETS ${ARG_NAME} RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
    set_property(GLOBAL APPEND PROPERTY LOOKUP_PROGRAMS ${ARG_NAME})
endfunction()

# lookup_add_test(NAME <unit>_test SOURCES ... DEPS ... [LABELS ...] [SLOW Suite.Test ...])
# One GoogleTest executable per unit, linked with lookup_test_support (tests/support); each
# TEST becomes its own ctest entry with LABELS. SLOW: the tests of this executable that take
# over 10 s, labelled `slow` as well (ctest -LE slow leaves them out).
function(lookup_add_test)
    cmake_parse_arguments(ARG "" "NAME" "SOURCES;DEPS;LABELS;SLOW" ${ARGN})
    add_executable(${ARG_NAME} ${ARG_SOURCES})
    target_link_libraries(${ARG_NAME} PRIVATE ${ARG_DEPS} lookup_test_support GTest::gtest
                                              GTest::gtest_main)
    target_compile_definitions(${ARG_NAME} PRIVATE
        LOOKUP_SOURCE_SHARE_DIR="${LOOKUP_SOURCE_SHARE_DIR}"
        LOOKUP_BINARY_DIR="${CMAKE_BINARY_DIR}")
    include(GoogleTest)
    # Test folders go under this build tree, not the shared /tmp: two build trees running
    # their tests at once (a CI clone beside a working copy) would remove each other's files.
    file(MAKE_DIRECTORY ${CMAKE_BINARY_DIR}/test-tmp)
    # An empty LABELS value would swallow the next property name (one label here; SLOW adds
    # `slow` to it).
    set(properties ENVIRONMENT "TMPDIR=${CMAKE_BINARY_DIR}/test-tmp")
    if(ARG_LABELS)
        list(APPEND properties LABELS ${ARG_LABELS})
    endif()
    gtest_discover_tests(${ARG_NAME} DISCOVERY_TIMEOUT 60 PROPERTIES ${properties})
    # The discovered names are known only at test time: ctest reads this file after the
    # discovered tests (TEST_INCLUDE_FILES in order); names not discovered are ignored.
    if(ARG_SLOW)
        set(slow_labels ${ARG_LABELS} slow)
        set(script "")
        foreach(test ${ARG_SLOW})
            string(APPEND script
                   "set_tests_properties([=[${test}]=] PROPERTIES LABELS \"${slow_labels}\")\n")
        endforeach()
        set(file ${CMAKE_CURRENT_BINARY_DIR}/${ARG_NAME}_slow.cmake)
        file(WRITE ${file} "${script}")
        set_property(DIRECTORY APPEND PROPERTY TEST_INCLUDE_FILES ${file})
    endif()
    if("fault" IN_LIST ARG_LABELS AND TARGET lookup_fault_tests)
        add_dependencies(lookup_fault_tests ${ARG_NAME})
    endif()
endfunction()
