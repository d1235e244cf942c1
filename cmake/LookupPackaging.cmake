# Debian package of the installed tree: `cpack -G DEB` in the build folder writes
# lookup_<version>_<arch>.deb. Its Depends line comes from dpkg-shlibdeps on the binaries
# (dpkg-dev, file: scripts/install-deps.sh), so it names exactly the Debian library packages
# LookUP links.
set(LOOKUP_PACKAGE_MAINTAINER "LookUP maintainers <lookup@localhost>"
    CACHE STRING "Maintainer field of the Debian package")

find_program(LOOKUP_DPKG dpkg)
set(lookup_deb_arch amd64)
if(LOOKUP_DPKG)
    execute_process(COMMAND ${LOOKUP_DPKG} --print-architecture
                    OUTPUT_VARIABLE lookup_deb_arch OUTPUT_STRIP_TRAILING_WHITESPACE)
endif()

set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGE_NAME lookup)
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGE_VENDOR "LookUP")
set(CPACK_PACKAGE_CONTACT "${LOOKUP_PACKAGE_MAINTAINER}")
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY
    "vision-only precise underground localisation from ceiling and forward cameras")
set(CPACK_DEBIAN_PACKAGE_DESCRIPTION
    "LookUP localises a vehicle in an underground mine from a ceiling camera and a forward\n\
camera against a surveyed reference database (Zeng et al., ICRA 2019), on MRPT.\n\
Programs: lookup-sim, lookup-survey, lookup-coarse, lookup-train, lookup-localize,\n\
lookup-eval; configuration presets, an example sensors.ini and a systemd unit in\n\
/usr/share/lookup; headers, static libraries and the CMake package for find_package(lookup).")
set(CPACK_DEBIAN_FILE_NAME "lookup_${PROJECT_VERSION}_${lookup_deb_arch}.deb")
set(CPACK_DEBIAN_PACKAGE_ARCHITECTURE ${lookup_deb_arch})
set(CPACK_DEBIAN_PACKAGE_SECTION science)
set(CPACK_DEBIAN_PACKAGE_PRIORITY optional)
set(CPACK_DEBIAN_PACKAGE_MAINTAINER "${LOOKUP_PACKAGE_MAINTAINER}")
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
# Building against the installed package (find_package(lookup)) needs the -dev packages of the
# dependencies; camera-calib (docs/vehicle.md) is in mrpt-apps.
set(CPACK_DEBIAN_PACKAGE_SUGGESTS
    "mrpt-apps, libmrpt-dev, libopencv-dev, libceres-dev, libeigen3-dev, libtorch-dev, nlohmann-json3-dev")
# dpkg-shlibdeps runs in the staging root; the project's own liblookup_obs.so is there.
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS_PRIVATE_DIRS "usr/${CMAKE_INSTALL_LIBDIR}")
set(CPACK_STRIP_FILES ON)
include(CPack)
