# Included by CTest after the discovered tests (tests/CMakeLists.txt): the COST of the longest tests, so that
# `ctest -j` starts them first when the build tree has no cost data of an earlier run (CI builds from scratch).
# Without it they start in definition order (test_scenes' last); on the measured times that costs a few seconds at
# -j2, more when a long test is added late.
# Each entry: test name, then its seconds in a Release run on 2 cores (measured; only the order matters).
set(lumen_test_costs
  "Scenes.CorotationalTet10PinchApproachesTheCalculixReference 62"
  "HardCasesCorotational.InvertingPointForce 34"
  "HardCasesCorotational.ModulusSweepScalesExactly 30"
  "HardCasesCorotational.ClosureThenFiveTimesTheClosingForce 28"
  "HardCases.SoakTenThousandFrames 26"
  "Scenes.AneurysmFullSceneNeverIntersects 16"
  "InstrumentScenes.GastroscopeInTheOesophagusTouchesTheWallFromInside 16"
  "InstrumentScenes.AFrameWithMoreContactsThanTheCapTakesTheSafeFallback 12"
  "HardCasesCorotational.NearlyIncompressible0499 14"
  "HapticsStiffness.LocalStiffnessOfAGraspIncludesTheHoldAndMatchesFiniteDifferences 14"
  "HardCasesCorotational.ForceStepInOneFrame 13"
  "HardCasesCorotational.NearlyIncompressible049 12"
  "HardCasesCorotational.BentTubeWallsTouchInTheBend 10"
  "InstrumentScenes.GrasperHoldsTheWallRigidlyWhileLiftingAndLetsGoWhenOpened 9"
  "HardCases.TwistCorotationalKeepsTheVolume 11"
  "RestrictedRecheck.FindsWhatTheFullRecheckFindsWhenTwoToolsPinchTheLumenShut 11"
  "RestrictedRecheck.FindsWhatTheFullRecheckFindsWhenAProbePressesTheTube 11"
  "InstrumentScenes.TwoToolsPinchTheLumenShutWithoutIntersection 11"
  "RestrictedRecheck.FindsWhatTheFullRecheckFindsWhenTheWallsMeet 9"
  "RestrictedDetection.FindsWhatTheFullDetectionFindsWhenTheWallsMeet 10"
  "RestrictedDetection.FindsWhatTheFullDetectionFindsWhenTwoToolsPinchTheLumenShut 10"
  "InstrumentScenes.ScopeInTheLumenPressesTheInnerWallWithoutIntersection 9"
  "InstrumentScenes.ProbePressNeverPenetratesAndTheOrganPushesBack 8"
  "Quadratic.PaperMeshSizesAndTimings 8"
  "HardCases.ForceStepDynamicSettlesToTheQuasiStaticState 7"
  "HardCases.ModulusSweepScalesExactly 7"
  "Scenes.AneurysmPairTetrahedralisedAtLoadKeepsItsSurfacesAndNeverIntersects 5"
  "Coupling.CarriedContactsStayInTheNonlinearEquilibrium 4")
# A test is named only if this tree discovered it (test_scenes is not built in the sanitizer tree).
set(lumen_discovered ${test_physics_TESTS} ${test_collision_TESTS} ${test_render_TESTS} ${test_engine_TESTS}
    ${lumen_engine_session_tests} ${lumen_engine_release_tests} ${lumen_scene_tests})
foreach(entry IN LISTS lumen_test_costs)
  string(REPLACE " " ";" entry "${entry}")
  list(GET entry 0 name)
  list(GET entry 1 seconds)
  list(FIND lumen_discovered "${name}" index)
  if(NOT index EQUAL -1)
    set_tests_properties("${name}" PROPERTIES COST ${seconds})
  endif()
endforeach()
