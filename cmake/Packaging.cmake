# Install rules and Debian packages (CPack DEB) of the host build; docs/install.md describes the result.
#   cmake --install build/host --prefix /usr/local          (system files, below, go to their system places)
#   (cd build/host && cpack -G DEB)  → build/host/packages/*.deb
# Packages (one per install component):
#   phalanx          daemon, CLI, firmware-sim, config example, docs, man pages, udev rules, systemd unit,
#                    the group's real-time limits; postinst creates the `phalanx` system group and user
#   libphalanx-dev   the client library with its headers, CMake package and pkg-config file: the install
#                    component `sdk` of sdk/CMakeLists.txt (which `cmake --install --component sdk` also installs)
#   python3-phalanx  the Python module (python/phalanx: the record reader and the compiled client bindings)
#   phalanx-firmware the MCU images, when tools/mcu has built them before this configure (build/mcu-*)
include(GNUInstallDirs)

# System files must sit where the system reads them, whatever the prefix: /etc for the config and limits.d.
# The unit and udev rules go below the prefix (systemd and udev read /usr/lib and /usr/local/lib alike).
set(PHALANX_SYSCONFDIR "/etc" CACHE PATH "where phalanx/phalanxd.yaml and security/limits.d/phalanx.conf go")
set(PHALANX_PYTHON_DIR "lib/python3/dist-packages" CACHE STRING "Python module directory below the prefix")
set(PHALANX_DOC_SUBDIR "${CMAKE_INSTALL_DATAROOTDIR}/doc/phalanx")
set(PHALANX_PKG_SRC ${PROJECT_SOURCE_DIR}/packaging)

# --- phalanx: the programs, config, docs, system integration
install(TARGETS phalanxd phalanx firmware-sim RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR} COMPONENT daemon)
install(FILES ${PROJECT_SOURCE_DIR}/config/phalanxd.yaml DESTINATION ${PHALANX_SYSCONFDIR}/phalanx COMPONENT daemon)
install(DIRECTORY DESTINATION ${PHALANX_SYSCONFDIR}/phalanx/profiles COMPONENT daemon)
install(FILES ${PHALANX_PKG_SRC}/limits/phalanx.conf DESTINATION ${PHALANX_SYSCONFDIR}/security/limits.d COMPONENT daemon)
install(FILES ${PHALANX_PKG_SRC}/udev/70-phalanx.rules DESTINATION lib/udev/rules.d COMPONENT daemon)
file(GLOB PHALANX_DOCS CONFIGURE_DEPENDS ${PROJECT_SOURCE_DIR}/docs/*.md)
install(FILES ${PROJECT_SOURCE_DIR}/README.md ${PHALANX_DOCS} DESTINATION ${PHALANX_DOC_SUBDIR} COMPONENT daemon)
install(FILES ${PROJECT_SOURCE_DIR}/config/phalanxd.yaml DESTINATION ${PHALANX_DOC_SUBDIR}/examples COMPONENT daemon)
install(DIRECTORY ${PROJECT_SOURCE_DIR}/config/profiles DESTINATION ${PHALANX_DOC_SUBDIR}/examples COMPONENT daemon)
# The unit names the installed programs: written at install time, when the final prefix is known (cpack: /usr).
install(CODE "
  set(PHALANX_BIN_DIR \"\${CMAKE_INSTALL_PREFIX}/${CMAKE_INSTALL_BINDIR}\")
  set(PHALANX_DOC_DIR \"\${CMAKE_INSTALL_PREFIX}/${PHALANX_DOC_SUBDIR}\")
  set(PHALANX_SYSCONF_DIR \"${PHALANX_SYSCONFDIR}\")
  configure_file(\"${PHALANX_PKG_SRC}/systemd/phalanxd.service.in\" \"${CMAKE_CURRENT_BINARY_DIR}/packaging/phalanxd.service\" @ONLY)
  file(INSTALL \"${CMAKE_CURRENT_BINARY_DIR}/packaging/phalanxd.service\" DESTINATION \"\${CMAKE_INSTALL_PREFIX}/lib/systemd/system\")
" COMPONENT daemon)

# Man pages from each program's --help (help2man, Debian package help2man; test set of tools/setup.sh).
find_program(PHALANX_HELP2MAN help2man)
find_program(PHALANX_GZIP gzip)
set(PHALANX_MAN_DIR ${CMAKE_CURRENT_BINARY_DIR}/packaging/man)
set(PHALANX_MAN_PAGES)
if(PHALANX_HELP2MAN AND PHALANX_GZIP)
  set(phalanxd_man_name "Phalanx host daemon: device sessions and the control API")
  set(phalanx_man_name "Phalanx command-line tool: sessions, records, design tools, API client")
  set(firmware-sim_man_name "Phalanx firmware on a simulated board (a device for phalanxd)")
  foreach(prog phalanxd phalanx firmware-sim)
    add_custom_command(OUTPUT ${PHALANX_MAN_DIR}/${prog}.1.gz
      COMMAND ${CMAKE_COMMAND} -E make_directory ${PHALANX_MAN_DIR}
      COMMAND ${PHALANX_HELP2MAN} --no-info --no-discard-stderr --version-string=${PROJECT_VERSION}
              --name=${${prog}_man_name} --section=1 --output=${PHALANX_MAN_DIR}/${prog}.1 $<TARGET_FILE:${prog}>
      COMMAND ${PHALANX_GZIP} -9nf ${PHALANX_MAN_DIR}/${prog}.1
      DEPENDS ${prog} VERBATIM)
    list(APPEND PHALANX_MAN_PAGES ${PHALANX_MAN_DIR}/${prog}.1.gz)
  endforeach()
  add_custom_target(man-pages ALL DEPENDS ${PHALANX_MAN_PAGES})
  install(FILES ${PHALANX_MAN_PAGES} DESTINATION ${CMAKE_INSTALL_MANDIR}/man1 COMPONENT daemon)
else()
  message(STATUS "help2man or gzip not found: no man pages (tools/setup.sh --test installs help2man)")
endif()

# --- python3-phalanx: the pure-Python files (a compiled extension is installed by its own rule)
install(DIRECTORY ${PROJECT_SOURCE_DIR}/python/phalanx DESTINATION ${PHALANX_PYTHON_DIR} COMPONENT python
        FILES_MATCHING PATTERN "*.py" PATTERN "__pycache__" EXCLUDE)

# --- phalanx-firmware: images of the cross builds present at configure time (tools/mcu/build.sh, ci.sh)
set(PHALANX_FIRMWARE_BUILD_ROOT ${PROJECT_SOURCE_DIR}/build CACHE PATH "where the build/mcu-<board> directories are")
file(GLOB PHALANX_FIRMWARE_IMAGES ${PHALANX_FIRMWARE_BUILD_ROOT}/mcu-*/phalanx-*.elf
     ${PHALANX_FIRMWARE_BUILD_ROOT}/mcu-*/phalanx-*.bin ${PHALANX_FIRMWARE_BUILD_ROOT}/mcu-*/phalanx-*.hex)
if(PHALANX_FIRMWARE_IMAGES)
  install(FILES ${PHALANX_FIRMWARE_IMAGES} DESTINATION ${CMAKE_INSTALL_DATAROOTDIR}/phalanx/firmware COMPONENT firmware)
  # The ELF images are Cortex-M programs for the boards, kept with their symbols for the debugger: lintian's
  # host-binary checks do not apply to them (packaging/debian/phalanx-firmware.lintian-overrides).
  install(FILES ${PHALANX_PKG_SRC}/debian/phalanx-firmware.lintian-overrides DESTINATION
          ${CMAKE_INSTALL_DATAROOTDIR}/lintian/overrides RENAME phalanx-firmware COMPONENT firmware)
endif()

# --- Debian changelog and copyright in every package's doc directory (Debian policy 12.5, 12.7)
set(PHALANX_DEB_CHANGELOG ${CMAKE_CURRENT_BINARY_DIR}/packaging/changelog.Debian.gz)
if(PHALANX_GZIP)
  add_custom_command(OUTPUT ${PHALANX_DEB_CHANGELOG}
    COMMAND ${CMAKE_COMMAND} -E make_directory ${CMAKE_CURRENT_BINARY_DIR}/packaging
    COMMAND ${PHALANX_GZIP} -9nc ${PHALANX_PKG_SRC}/debian/changelog > ${PHALANX_DEB_CHANGELOG}
    DEPENDS ${PHALANX_PKG_SRC}/debian/changelog)
  add_custom_target(deb-changelog ALL DEPENDS ${PHALANX_DEB_CHANGELOG})
endif()
set(PHALANX_COMPONENTS daemon sdk python)
if(PHALANX_FIRMWARE_IMAGES)
  list(APPEND PHALANX_COMPONENTS firmware)
endif()
set(PHALANX_DEB_daemon phalanx)
set(PHALANX_DEB_sdk libphalanx-dev)
set(PHALANX_DEB_python python3-phalanx)
set(PHALANX_DEB_firmware phalanx-firmware)
foreach(comp IN LISTS PHALANX_COMPONENTS)
  install(FILES ${PHALANX_PKG_SRC}/debian/copyright DESTINATION ${CMAKE_INSTALL_DATAROOTDIR}/doc/${PHALANX_DEB_${comp}}
          COMPONENT ${comp})
  if(PHALANX_GZIP)
    install(FILES ${PHALANX_DEB_CHANGELOG} DESTINATION ${CMAKE_INSTALL_DATAROOTDIR}/doc/${PHALANX_DEB_${comp}}
            COMPONENT ${comp})
  endif()
endforeach()

# --- CPack
set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGE_NAME phalanx)
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGE_VENDOR "Phalanx")
set(CPACK_PACKAGE_CONTACT "Phalanx developers <phalanx-dev@example.org>")
set(CPACK_PACKAGE_DIRECTORY ${CMAKE_BINARY_DIR}/packages)
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_STRIP_FILES ON)
set(CPACK_COMPONENTS_ALL ${PHALANX_COMPONENTS})
set(CPACK_DEB_COMPONENT_INSTALL ON)
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_RELEASE 1)
set(CPACK_DEBIAN_PACKAGE_SECTION misc)
set(CPACK_DEBIAN_PACKAGE_PRIORITY optional)
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
set(CPACK_DEBIAN_PACKAGE_CONTROL_STRICT_PERMISSION ON)
set(CPACK_DEBIAN_PACKAGE_HOMEPAGE "https://github.com/phalanx-haptics/phalanx")
foreach(comp IN LISTS PHALANX_COMPONENTS)
  string(TOUPPER ${comp} COMP)
  set(CPACK_DEBIAN_${COMP}_PACKAGE_NAME ${PHALANX_DEB_${comp}})
endforeach()
set(CPACK_COMPONENT_DAEMON_DESCRIPTION "host daemon, CLI and simulated firmware of the Phalanx haptics stack
phalanxd runs the 1 kHz control session of a Phalanx haptic device (glove5,
sea_finger, pantograph) over USB, CAN or serial, with one limits stage for
every command, and serves a control API to the group phalanx. phalanx is the
command-line tool; firmware-sim runs the device firmware on a simulated board.
Includes udev rules, a systemd unit and the group's real-time limits.")
set(CPACK_DEBIAN_DAEMON_PACKAGE_DEPENDS "passwd, libcap2-bin")
# Renamed to the control-file names dpkg wants (postinst, postrm) in a directory of their own.
file(MAKE_DIRECTORY ${CMAKE_CURRENT_BINARY_DIR}/packaging/daemon-control)
configure_file(${PHALANX_PKG_SRC}/debian/phalanx.postinst ${CMAKE_CURRENT_BINARY_DIR}/packaging/daemon-control/postinst COPYONLY
               FILE_PERMISSIONS OWNER_READ OWNER_WRITE OWNER_EXECUTE GROUP_READ GROUP_EXECUTE WORLD_READ WORLD_EXECUTE)
configure_file(${PHALANX_PKG_SRC}/debian/phalanx.postrm ${CMAKE_CURRENT_BINARY_DIR}/packaging/daemon-control/postrm COPYONLY
               FILE_PERMISSIONS OWNER_READ OWNER_WRITE OWNER_EXECUTE GROUP_READ GROUP_EXECUTE WORLD_READ WORLD_EXECUTE)
file(WRITE ${CMAKE_CURRENT_BINARY_DIR}/packaging/daemon-control/conffiles
     "${PHALANX_SYSCONFDIR}/phalanx/phalanxd.yaml\n${PHALANX_SYSCONFDIR}/security/limits.d/phalanx.conf\n")
set(CPACK_DEBIAN_DAEMON_PACKAGE_CONTROL_EXTRA
    ${CMAKE_CURRENT_BINARY_DIR}/packaging/daemon-control/postinst ${CMAKE_CURRENT_BINARY_DIR}/packaging/daemon-control/postrm
    ${CMAKE_CURRENT_BINARY_DIR}/packaging/daemon-control/conffiles)
set(CPACK_COMPONENT_SDK_DESCRIPTION "Phalanx client library and its development files
libphalanx connects a program to phalanxd's client channel to read a device's
state and command it at up to 1 kHz through the daemon's limits stage. With
its C and C++ headers, CMake package and pkg-config file.")
set(CPACK_DEBIAN_SDK_PACKAGE_SECTION libdevel)
set(CPACK_DEBIAN_PACKAGE_GENERATE_SHLIBS ON)
file(WRITE ${CMAKE_CURRENT_BINARY_DIR}/packaging/sdk-control/triggers "activate-noawait ldconfig\n")
set(CPACK_DEBIAN_SDK_PACKAGE_CONTROL_EXTRA ${CMAKE_CURRENT_BINARY_DIR}/packaging/sdk-control/triggers)
set(CPACK_COMPONENT_PYTHON_DESCRIPTION "Phalanx Python module
The phalanx package for Python 3: client bindings and session record reader.")
set(CPACK_DEBIAN_PYTHON_PACKAGE_SECTION python)
# Architecture-dependent: it carries the compiled extension (sdk/CMakeLists.txt installs it into this component).
set(CPACK_DEBIAN_PYTHON_PACKAGE_DEPENDS "python3, python3-numpy")
set(CPACK_COMPONENT_FIRMWARE_DESCRIPTION "Phalanx firmware images for Cortex-M4F boards
ELF, binary and Intel HEX images of every device app for the STM32G474 board
and the emulated mps2-an386 and ast1030-evb boards.")
set(CPACK_DEBIAN_FIRMWARE_PACKAGE_ARCHITECTURE all)
set(CPACK_DEBIAN_FIRMWARE_PACKAGE_SHLIBDEPS OFF)
include(CPack)
