// POV-Ray twin of bench/solids.toml for bench/equal_work.py: the same
// camera, objects, materials and light, as bench/whitted.pov maps them.
// POV-Ray is left-handed, so z is negated: points and normals get -z, and a
// rotation about the x or y axis turns the other way (about z it would not).
#version 3.7;
global_settings { assumed_gamma 1.0 max_trace_level 8 adc_bailout 0.001 ambient_light rgb <0.15, 0.15, 0.15> }
background { rgb <0.25, 0.45, 0.85> }
camera {
  perspective
  location <0, 2.5, -8>
  look_at <0, 1, 0>
  right x*4/3
  angle 51.78  // horizontal: our 40° vertical at 4:3
}
light_source {
  <4, 9, -7> color rgb 1
  // The sphere light of radius 0.5 with 16 samples: a 4×4 circular area light.
  area_light <1, 0, 0>, <0, 0, 1>, 4, 4 circular orient
}

#declare Mirror = texture {
  pigment { color rgb <0.8, 0.8, 0.85> }
  finish { ambient 0.1 diffuse 0.15 phong 0.8 phong_size 80 reflection 0.75 }
}
#declare Glass = material {
  texture {
    pigment { color rgbt <1, 1, 1, 0.9> }
    finish { ambient 0 diffuse 0 phong 0.8 phong_size 120 reflection 0.1 }
  }
  interior { ior 1.5 }
}
#macro Plain(C)
  texture {
    pigment { color rgb C }
    finish { ambient 0.3 diffuse 0.7 phong 0.3 phong_size 30 }
  }
#end
#declare Red = Plain(<0.85, 0.15, 0.1>)
#declare Blue = Plain(<0.15, 0.3, 0.85>)
#declare Green = Plain(<0.15, 0.7, 0.25>)
#declare Gold = Plain(<0.9, 0.7, 0.2>)

// The floor: a slab, its top at y = 0.
box {
  <-8, -0.3, 12>, <8, 0, -5>
  pigment { checker color rgb <0.9, 0.9, 0.88> color rgb <0.25, 0.25, 0.3> }
  finish { ambient 0.4 diffuse 0.7 phong 0.2 phong_size 20 }
}

// Back row.
disc { <-0.6, 1.7, 5.5>, <0.15, 0, -1>, 1.6 texture { Mirror } }  // round mirror
box {  // mirror box
  <-1, 0, 0.6>, <1, 1.6, -0.6>
  texture { Mirror }
  rotate -25*y
  translate <-2.8, 0, 3.2>
}
cylinder { <0.9, 0, 3.4>, <0.9, 2.6, 3.4>, 0.6 texture { Mirror } }  // mirror column
torus {  // standing ring
  0.8, 0.22
  texture { Gold }
  rotate -90*x
  rotate 20*y
  translate <3.1, 1.03, 3>
}
box {  // blue block
  <-0.5, 0, 0.4>, <0.5, 0.7, -0.4>
  texture { Blue }
  rotate 15*y
  translate <-0.4, 0, 2.6>
}

// Middle row.
cone { <-3.3, 0, 0.8>, 0.6, <-3.3, 1.7, 0.8>, 0 texture { Red } }  // red cone
cone { <-1.5, 0, 1.1>, 0.75, <-1.5, 1, 1.1>, 0.35 texture { Mirror } }  // mirror frustum
torus { 0.45, 0.12 material { Glass } translate <-1.5, 1.12, 1.1> }  // glass ring on the frustum
torus { 0.7, 0.2 material { Glass } translate <0.9, 0.2, 0.9> }  // glass ring on the floor
disc { <2.9, 1, 0.6>, <-0.35, 0, -1>, 0.8, 0.35 texture { Red } }  // ring
cone { <4.4, 0.4, 1.6>, 0.4, <3.7, 0.4, 2.6>, 0.1 texture { Green } }  // green cone on its side

// Front row.
cylinder { <-2.5, 0.35, -1.3>, <-0.9, 0.35, -1.6>, 0.35 material { Glass } }  // glass log
box {  // glass block
  <-0.4, 0.02, 0.4>, <0.4, 0.82, -0.4>
  material { Glass }
  rotate -40*y
  translate <0.1, 0, -1.5>
}
disc { <0.1, 0.83, -1.5>, <0, 1, 0>, 0.3 texture { Blue } }  // blue lid
torus {  // mirror ring
  0.5, 0.16
  texture { Mirror }
  rotate -60*x
  translate <1.5, 0.75, -1.7>
}
cylinder { <2.6, 0, -1.2>, <2.6, 0.9, -1.2>, 0.4 open texture { Green } }  // green tube
