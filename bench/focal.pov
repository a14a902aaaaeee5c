// POV-Ray twin of bench/focal.toml (depth of field) for bench/equal_work.py:
// same camera, objects, materials and light. POV-Ray is left-handed, so z
// is negated.
//
// The lens. POV-Ray deflects each blur sample's eye point by
// (aperture / 2) * (a point of its sample grid + jitter), and its grid
// lies in a disc of radius 0.5 (a hexagonal grid, then Halton points on
// that disc; the jitter adds up to 0.5 / sqrt(blur_samples) across), so
// its lens is a disc of radius aperture / 4: aperture 0.48 here is
// Prism's lens radius 0.12 (`aperture = 0.12` in the .toml). Both aim
// each sample at the point the pinhole ray meets on the plane in focus,
// whose depth is focal_point's distance from the camera (POV-Ray) or
// look_at's (Prism): the same point here, on the view axis.
//
// variance 0: POV-Ray otherwise stops a pixel's blur samples early once
// their variance looks small (confidence test), which biases the blur and
// changes the work; with variance 0 every pixel traces all blur_samples
// rays, as Prism traces spp = 16.
#version 3.7;
global_settings { assumed_gamma 1.0 max_trace_level 8 adc_bailout 0.001 ambient_light rgb <0.15, 0.15, 0.15> }
background { rgb <0.25, 0.45, 0.85> }
camera {
  perspective
  location <0, 1.6, -6>
  look_at <0, 0.7, 2>
  right x*4/3
  angle 51.8  // horizontal: our 40° vertical at 4:3
  aperture 0.48
  focal_point <0, 0.7, 2>
  blur_samples 16
  variance 0
}
light_source { <4, 9, -7> color rgb 1 }

polygon {
  4, <-6, 0, -5>, <6, 0, -5>, <6, 0, 16>, <-6, 0, 16>
  pigment { checker color rgb <0.95, 0.9, 0.1> color rgb <0.85, 0.05, 0.05> }
  finish { ambient 0.4 diffuse 0.7 phong 0.2 phong_size 20 }
}
#declare Red = texture {
  pigment { color rgb <0.8, 0.15, 0.1> }
  finish { ambient 0.2 diffuse 0.7 phong 0.5 phong_size 60 }
}
sphere { <-2, 0.7, -3>, 0.7 texture { Red } }
sphere {
  <-1, 0.7, -0.5>, 0.7
  pigment { color rgbt <1, 1, 1, 0.9> }
  finish { ambient 0 diffuse 0 phong 0.8 phong_size 120 reflection 0.1 }
  interior { ior 1.5 }
}
sphere {
  <0, 0.7, 2>, 0.7
  pigment { color rgb <0.8, 0.8, 0.85> }
  finish { ambient 0.1 diffuse 0.15 phong 0.8 phong_size 80 reflection 0.75 }
}
sphere {
  <1, 0.7, 4.5>, 0.7
  pigment { color rgb <0.15, 0.3, 0.85> }
  finish { ambient 0.2 diffuse 0.7 phong 0.5 phong_size 60 }
}
sphere { <2, 0.7, 7>, 0.7 texture { Red } }
