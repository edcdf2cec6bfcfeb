# The longest test cases and their cost (tests/apply_test_costs.cmake sets it as COST, so that `ctest -j` starts
# them first when the build tree has no cost data of an earlier run: CI builds from scratch); each of them runs in a
# process of its own (tests/discover_groups.cmake), the other cases in groups.
# Without a cost they start in definition order (test_scenes' last); on the measured times that costs a few seconds at
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
