// POV-Ray twin of bench/whitted.toml for bench/run.py: same camera, objects,
// materials and light. POV-Ray is left-handed, so z is negated.
#version 3.7;
global_settings { assumed_gamma 1.0 max_trace_level 8 adc_bailout 0.001 ambient_light rgb <0.15, 0.15, 0.15> }
background { rgb <0.25, 0.45, 0.85> }
camera {
  perspective
  location <0, 1.6, -6>
  look_at <0, 1, 0>
  right x*4/3
  angle 51.8  // horizontal: our 40° vertical at 4:3
}
light_source {
  <4, 9, -7> color rgb 1
  // The sphere light of radius 0.5 with 16 samples: a 4×4 circular area light.
  area_light <1, 0, 0>, <0, 0, 1>, 4, 4 circular orient
}

polygon {
  4, <-5, 0, -4>, <5, 0, -4>, <5, 0, 12>, <-5, 0, 12>
  pigment { checker color rgb <0.95, 0.9, 0.1> color rgb <0.85, 0.05, 0.05> }
  finish { ambient 0.4 diffuse 0.7 phong 0.2 phong_size 20 }
}
sphere {
  <-1, 1.35, 1.8>, 1.35
  pigment { color rgb <0.8, 0.8, 0.85> }
  finish { ambient 0.1 diffuse 0.15 phong 0.8 phong_size 80 reflection 0.75 }
}
sphere {
  <0.7, 1, -0.6>, 0.8
  pigment { color rgbt <1, 1, 1, 0.9> }
  finish { ambient 0 diffuse 0 phong 0.8 phong_size 120 reflection 0.1 }
  interior { ior 1.5 }
}
