-- The camera of the bundled example (BuilderBot-like, 320x240): pixels, OpenCV's meaning.
-- tag_size is the side of the tag's black square in metres, so poses come out in metres.
return {
  fx = 313.9,
  fy = 313.9,
  cx = 159.5,
  cy = 119.5,
  width = 320,
  height = 240,
  tag_size = 0.024,
}
