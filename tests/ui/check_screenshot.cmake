# Starts the app under xvfb-run with --screenshot and checks what the PNG shows (screenshot_content: the
# phantom's frame found in it, the organ drawn where the camera puts it).
# A first start, in a settings folder of its own: the user's window layout neither shapes the picture nor is
# overwritten by the test.
file(REMOVE ${OUT})
get_filename_component(home ${OUT} DIRECTORY)
set(home ${home}/xvfb-screenshot-home)
file(REMOVE_RECURSE ${home})
file(MAKE_DIRECTORY ${home}/config ${home}/data)
execute_process(COMMAND ${CMAKE_COMMAND} -E env XDG_CONFIG_HOME=${home}/config XDG_DATA_HOME=${home}/data
                        ${XVFB_RUN} -a -s "-screen 0 1600x900x24" ${APP} --screenshot ${OUT}
  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err TIMEOUT 240)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "the GUI exited with ${rc}: ${err}")
endif()
if(NOT EXISTS ${OUT})
  message(FATAL_ERROR "no screenshot was written")
endif()
execute_process(COMMAND ${CHECK} ${OUT} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err TIMEOUT 120)
message(STATUS "${out}")
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "the screenshot does not show the case: ${err}")
endif()
