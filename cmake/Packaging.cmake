# The Debian package (issue 39): `cpack -G DEB` in the build folder (or `cmake --build build --target package`)
# writes rehearse_<version>_<arch>.deb from the install rules. Its Depends come from dpkg-shlibdeps (the libraries
# the program links) plus what no linker sees: Qt's platform plugins (xcb, offscreen) and its SQLite driver, which
# opens case files. Mesa's software renderer is recommended (the training database's libpq is linked: a Depends).
include(GNUInstallDirs)

# Documentation Debian policy asks of every package: the copyright, and the changelog compressed with gzip -9n
# (no name or time stamp in the header, so the package is the same byte for byte when rebuilt).
find_program(REHEARSE_GZIP gzip REQUIRED)
set(_changelog_gz ${PROJECT_BINARY_DIR}/packaging/changelog.gz)
add_custom_command(OUTPUT ${_changelog_gz}
  COMMAND ${CMAKE_COMMAND} -E make_directory ${PROJECT_BINARY_DIR}/packaging
  COMMAND ${REHEARSE_GZIP} -9n -c ${PROJECT_SOURCE_DIR}/packaging/changelog > ${_changelog_gz}
  DEPENDS ${PROJECT_SOURCE_DIR}/packaging/changelog
  COMMENT "Compressing the package's changelog")
add_custom_target(rehearse_changelog ALL DEPENDS ${_changelog_gz})
install(FILES ${_changelog_gz} ${PROJECT_SOURCE_DIR}/packaging/copyright DESTINATION ${CMAKE_INSTALL_DOCDIR})

set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGE_NAME rehearse)
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGE_VENDOR "The Rehearse developers")
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY "surgical gesture rehearsal on the organ seen in an endoscope frame")
# The extended description (CPack puts the summary above it, indents each line and turns the empty one into " .").
set(CPACK_DEBIAN_PACKAGE_DESCRIPTION
  "A surgeon picks a frame from the endoscope; the pre-operative organ model
is registered onto it (a rigid alignment by hand, then an elastic fit onto
the outline an assistant sketched, with how sure the fit is); the organ's
appearance and the light are estimated from the frame; and the surgeon
grasps, pulls, clips, burns and cuts the organ with the mouse in a view that
looks like the frame itself.

Trainers replay and review recorded sessions, with the forces, cuts and
incorrect actions of each.")
set(CPACK_DEBIAN_PACKAGE_MAINTAINER "The Rehearse developers <rehearse@example.org>")
set(CPACK_DEBIAN_PACKAGE_SECTION science)
set(CPACK_DEBIAN_PACKAGE_PRIORITY optional)
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
set(CPACK_DEBIAN_PACKAGE_DEPENDS "qt6-qpa-plugins, libqt6sql6-sqlite")
set(CPACK_DEBIAN_PACKAGE_RECOMMENDS "libgl1-mesa-dri")
set(CPACK_DEBIAN_PACKAGE_CONTROL_STRICT_PERMISSION ON)
set(CPACK_STRIP_FILES ON)
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_PACKAGE_CONTACT "rehearse@example.org")
include(CPack)
