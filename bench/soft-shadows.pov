// POV-Ray twin of scenes/soft-shadows.toml for bench/run.py. Sphere lights
// become circular, oriented area lights with the same number of samples
// (6×6 = 36 and 8×8 = 64), non-adaptive. z is negated (left-handed).
#version 3.7;
global_settings { assumed_gamma 1.0 max_trace_level 8 ambient_light rgb <0.05, 0.05, 0.05> }
background { rgb <0.05, 0.05, 0.08> }
camera {
  perspective
  location <0, 8, -10>
  look_at <0, 0, -0.3>
  right x*720/300
  angle 79.2  // horizontal: our 36° vertical at 720:300
}
light_source { <-5, 3, 0> color rgb 7 fade_distance 1 fade_power 2 }
light_source {
  <0, 3, 0> color rgb 7 fade_distance 1 fade_power 2
  area_light <0.8, 0, 0>, <0, 0, 0.8>, 6, 6 circular orient
}
light_source {
  <5, 3, 0> color rgb 7 fade_distance 1 fade_power 2
  area_light <2, 0, 0>, <0, 0, 2>, 8, 8 circular orient
}
plane { y, 0 pigment { color rgb <0.9, 0.9, 0.85> } finish { ambient 1 diffuse 1 } }
#declare Ball = sphere { 0, 0.6
  pigment { color rgb <0.2, 0.4, 0.9> }
  finish { ambient 1 diffuse 0.8 phong 0.4 phong_size 40 }
}
object { Ball translate <-5, 1.2, 0> }
object { Ball translate <0, 1.2, 0> }
object { Ball translate <5, 1.2, 0> }
