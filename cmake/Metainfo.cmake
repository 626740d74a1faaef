# Writes the AppStream metainfo OUTPUT from its template IN. AppStream names screenshots by web address (an https URL
# a software centre downloads), and Rehearse has no public host of its own: with URL (REHEARSE_SCREENSHOT_URL, where
# docs/ is published) the metainfo lists the program's own screenshots from docs/ under it; without one it lists none
# rather than an address nobody serves. Script mode: cmake -DIN=... -DOUTPUT=... [-DURL=https://...] [-DDOCS=docs/]
# -P Metainfo.cmake (DOCS, when given, must hold every image named).
if(NOT IN OR NOT OUTPUT)
  message(FATAL_ERROR "Metainfo: IN and OUTPUT are needed")
endif()
set(SCREENSHOTS "")
if(URL)
  if(NOT URL MATCHES "^https://[^/]+")
    message(FATAL_ERROR "REHEARSE_SCREENSHOT_URL must be an https:// address (AppStream's screenshots are web addresses), not '${URL}'")
  endif()
  if(NOT URL MATCHES "/$")
    string(APPEND URL "/")
  endif()
  # image; caption (the first is the default screenshot)
  set(shots
    "screenshot.png|The main window on the built-in case: the frame, the organ drawn through the camera, the workflow"
    "step3-contour.png|Step 3: the assistant sketches the organ's outline on the frame"
    "step5-fit.png|Step 5: the elastic fit onto the outline, with where the organ may be"
    "step7-grasp-pull-cut.png|Step 7: the surgeon grasps, pulls and cuts the organ in the frame"
    "review.png|The trainer's review: two attempts side by side, the timeline and the metrics")
  string(APPEND SCREENSHOTS "  <screenshots>\n")
  set(kind " type=\"default\"")
  foreach(shot IN LISTS shots)
    string(REPLACE "|" ";" parts "${shot}")
    list(GET parts 0 image)
    list(GET parts 1 caption)
    if(DOCS AND NOT EXISTS "${DOCS}/${image}")
      message(FATAL_ERROR "Metainfo: the screenshot ${DOCS}/${image} does not exist")
    endif()
    string(APPEND SCREENSHOTS "    <screenshot${kind}>\n      <caption>${caption}</caption>\n"
                              "      <image>${URL}${image}</image>\n    </screenshot>\n")
    set(kind "")
  endforeach()
  string(APPEND SCREENSHOTS "  </screenshots>\n")
endif()
configure_file("${IN}" "${OUTPUT}" @ONLY)
