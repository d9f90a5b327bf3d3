# cmake -DNODE=... -DSCRIPT=tests/browser/view_test.mjs -DPAGE=... -P run_view_test.cmake
# Runs the browser test of a page; every exit but 0 fails (2 says Chromium or playwright-core is
# missing, which scripts/setup.sh installs: a test command that ran the setup has them).
if(NOT NODE)
  message(FATAL_ERROR "node (Node.js) not found: scripts/setup.sh installs it (Debian package nodejs)")
endif()
if(NOT EXISTS "${PAGE}")
  message(FATAL_ERROR "no page ${PAGE}")
endif()
execute_process(COMMAND "${NODE}" "${SCRIPT}" "${PAGE}" --screenshot "${PAGE}.png" RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "the browser test of ${PAGE} did not pass (exit ${rc}; 2: Chromium or playwright-core missing)")
endif()
