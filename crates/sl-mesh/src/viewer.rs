//! A self-contained interactive 3-D viewer page: one HTML file with the geometry and its
//! script inline (no network, no library, works from `file://`), drawn with WebGL 1 —
//! every browser of the last ten years has it, headless Chromium included (software
//! rendering). Drag to rotate, wheel to zoom, buttons to switch the layers and the colouring.
//!
//! The geometry is embedded as base64 of little-endian `f32` positions and normals and `u32`
//! indices, relative to the centre of the models' box (so `f32` keeps 10 µm on a metre-sized
//! scene), scan colours as `u8` RGB.
//!
//! The colour button cycles through the colourings the layers have: shaded (grey), scan colour
//! (the mesh's vertex colours, the cloud's point colours) and error; `?colour=scan` or
//! `?colour=error` after the page's address opens it in that colouring.

use std::fmt::Write as _;

use nalgebra::Point3;
use sl_cloud::{PointCloud, TriangleMesh, colormap};

use crate::MeshError;
use crate::adjacency::check_indices;
use crate::files::check_per_vertex;
use crate::measure::vertex_normals;

/// Colour-map stops the page uses, sampled from `sl_cloud::colormap` so the page and the PNG
/// error maps read the same.
const LEGEND_STOPS: usize = 9;

/// Weight of the shading on a mesh drawn in its scan colours: a texel of the brightest lit
/// side shows its colour as is, the darkest side at 1 − 0.8 × this (60 %). Scan colours carry
/// the light of the scene already; half the page's shading keeps the shape readable without
/// darkening them past recognition.
const SCAN_SHADING: f32 = 0.5;

/// One layer of the page: a mesh (triangles) or a cloud (points).
#[derive(Debug, Clone, Copy)]
pub enum ViewerLayer<'a> {
    /// A triangle mesh, smooth-shaded.
    Mesh {
        /// Name shown on its button.
        name: &'a str,
        /// The mesh.
        mesh: &'a TriangleMesh,
        /// Signed error per vertex (mm; NaN: no error known), for the error colouring.
        errors_mm: Option<&'a [f32]>,
        /// Colour per vertex (the scan's colour, RGB), for the scan colouring.
        colours: Option<&'a [[u8; 3]]>,
    },
    /// A point cloud, drawn as points; its colours (`PointCloud::colors`), when it has them,
    /// for the scan colouring.
    Cloud {
        /// Name shown on its button.
        name: &'a str,
        /// The cloud.
        cloud: &'a PointCloud,
        /// Signed error per point (mm; NaN: no error known).
        errors_mm: Option<&'a [f32]>,
    },
}

/// Options of [`viewer_html`].
#[derive(Debug, Clone, PartialEq)]
pub struct ViewerConfig {
    /// Page title.
    pub title: String,
    /// Error colouring: blue at `−range`, red at `+range` (mm).
    pub error_range_mm: f32,
    /// Clouds larger than this are thinned (every k-th point) to keep the page light.
    pub max_cloud_points: usize,
}

impl Default for ViewerConfig {
    fn default() -> Self {
        Self {
            title: "structured-light 3-D view".into(),
            // As `sl_metrology::DEFAULT_HEAT_MAP_RANGE_MM` (twice the 0.05 mm probing target).
            error_range_mm: 0.1,
            max_cloud_points: 300_000,
        }
    }
}

fn base64(bytes: &[u8]) -> String {
    const ABC: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            chunk.get(1).copied().unwrap_or(0),
            chunk.get(2).copied().unwrap_or(0),
        ];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for k in 0..4 {
            if k <= chunk.len() {
                out.push(ABC[((n >> (18 - 6 * k)) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// What the page holds of one layer, before encoding.
struct LayerData<'a> {
    name: &'a str,
    /// `"mesh"` or `"cloud"`.
    kind: &'static str,
    pts: Vec<Point3<f64>>,
    normals: Vec<nalgebra::Vector3<f64>>,
    errors: Option<Vec<f32>>,
    colours: Option<Vec<[u8; 3]>>,
    /// Triangle corners (meshes).
    index: Vec<u32>,
}

fn f32_bytes(values: impl Iterator<Item = f32>) -> Vec<u8> {
    values.flat_map(f32::to_le_bytes).collect()
}

/// The viewer page for `layers`.
///
/// # Errors
/// [`MeshError::InvalidMesh`] for a triangle index out of range or an error array that is not
/// one value per vertex (point); [`MeshError::AttributeLength`] for colours that are not one
/// per vertex; [`MeshError::InvalidParameter`] without any layer or for a non-positive range.
///
/// ```
/// use sl_mesh::{ViewerConfig, ViewerLayer, viewer_html};
/// # let mesh = sl_cloud::TriangleMesh { vertices: vec![nalgebra::Point3::origin(); 3], triangles: vec![[0, 1, 2]] };
/// let html = viewer_html(&[ViewerLayer::Mesh { name: "mesh", mesh: &mesh, errors_mm: None, colours: None }], &ViewerConfig::default())?;
/// assert!(html.starts_with("<!DOCTYPE html>") && !html.contains("http"));
/// // With the scan's colours: the page offers "colour: scan" (`?colour=scan` opens it so).
/// let colours = [[200, 40, 40]; 3];
/// let layer = ViewerLayer::Mesh { name: "mesh", mesh: &mesh, errors_mm: None, colours: Some(&colours) };
/// assert!(viewer_html(&[layer], &ViewerConfig::default())?.contains("col:\""));
/// # Ok::<(), sl_mesh::MeshError>(())
/// ```
pub fn viewer_html(layers: &[ViewerLayer<'_>], cfg: &ViewerConfig) -> Result<String, MeshError> {
    if layers.is_empty() {
        return Err(MeshError::invalid(
            "layers",
            0,
            "the page needs at least one layer",
        ));
    }
    if !(cfg.error_range_mm.is_finite() && cfg.error_range_mm > 0.0) {
        return Err(MeshError::invalid(
            "ViewerConfig::error_range_mm",
            cfg.error_range_mm,
            "must be positive",
        ));
    }
    // Common centre and size.
    let (mut lo, mut hi) = (
        Point3::new(f64::INFINITY, f64::INFINITY, f64::INFINITY),
        Point3::new(f64::NEG_INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY),
    );
    for layer in layers {
        let pts: &[Point3<f64>] = match layer {
            ViewerLayer::Mesh { mesh, .. } => &mesh.vertices,
            ViewerLayer::Cloud { cloud, .. } => cloud.positions(),
        };
        for p in pts
            .iter()
            .filter(|p| p.coords.iter().all(|c| c.is_finite()))
        {
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
    }
    let (centre, radius) = if lo.x <= hi.x {
        (
            nalgebra::center(&lo, &hi),
            ((hi - lo).norm() * 0.5).max(1e-9),
        )
    } else {
        (Point3::origin(), 1.0)
    };
    let mut js_layers = String::from("[");
    for layer in layers {
        let LayerData {
            name,
            kind,
            pts,
            normals,
            errors,
            colours,
            index,
        } = match layer {
            ViewerLayer::Mesh {
                name,
                mesh,
                errors_mm,
                colours,
            } => {
                check_indices(mesh)?;
                if let Some(e) = errors_mm
                    && e.len() != mesh.vertices.len()
                {
                    return Err(MeshError::InvalidMesh(format!(
                        "layer '{name}': {} errors for {} vertices",
                        e.len(),
                        mesh.vertices.len()
                    )));
                }
                if let Some(c) = colours {
                    check_per_vertex(mesh, c, "colours")?;
                }
                LayerData {
                    name,
                    kind: "mesh",
                    pts: mesh.vertices.clone(),
                    normals: vertex_normals(mesh),
                    errors: errors_mm.map(<[f32]>::to_vec),
                    colours: colours.map(<[[u8; 3]]>::to_vec),
                    index: mesh.triangles.iter().flatten().copied().collect(),
                }
            }
            ViewerLayer::Cloud {
                name,
                cloud,
                errors_mm,
            } => {
                if let Some(e) = errors_mm
                    && e.len() != cloud.len()
                {
                    return Err(MeshError::InvalidMesh(format!(
                        "layer '{name}': {} errors for {} points",
                        e.len(),
                        cloud.len()
                    )));
                }
                let step = cloud.len().div_ceil(cfg.max_cloud_points.max(1)).max(1);
                let keep: Vec<usize> = (0..cloud.len())
                    .step_by(step)
                    .filter(|&i| cloud.positions()[i].coords.iter().all(|c| c.is_finite()))
                    .collect();
                let nrm = keep
                    .iter()
                    .map(|&i| cloud.normals().map_or(nalgebra::Vector3::zeros(), |n| n[i]))
                    .collect();
                LayerData {
                    name,
                    kind: "cloud",
                    pts: keep.iter().map(|&i| cloud.positions()[i]).collect(),
                    normals: nrm,
                    errors: errors_mm.map(|e| keep.iter().map(|&i| e[i]).collect()),
                    colours: cloud.colors().map(|c| keep.iter().map(|&i| c[i]).collect()),
                    index: Vec::new(),
                }
            }
        };
        let pos = f32_bytes(
            pts.iter()
                .flat_map(|p| (p - centre).iter().map(|&c| c as f32).collect::<Vec<_>>()),
        );
        let nrm = f32_bytes(
            normals
                .iter()
                .flat_map(|n| [n.x as f32, n.y as f32, n.z as f32]),
        );
        let err = errors.map(|e| f32_bytes(e.into_iter()));
        let col = colours.map(|c| c.concat());
        let idx: Vec<u8> = index.iter().flat_map(|i| i.to_le_bytes()).collect();
        let name_json: String = name
            .chars()
            .filter(|c| !c.is_control() && *c != '"' && *c != '\\' && *c != '<')
            .collect();
        let _ = write!(
            js_layers,
            "{{name:\"{name_json}\",kind:\"{kind}\",pos:\"{}\",nrm:\"{}\",err:{},col:{},idx:\"{}\"}},",
            base64(&pos),
            base64(&nrm),
            err.map_or("null".to_owned(), |e| format!("\"{}\"", base64(&e))),
            col.map_or("null".to_owned(), |c| format!("\"{}\"", base64(&c))),
            base64(&idx)
        );
    }
    js_layers.push(']');
    let stops: Vec<String> = (0..LEGEND_STOPS)
        .map(|k| {
            let c = colormap(k as f64 / (LEGEND_STOPS - 1) as f64);
            format!("[{},{},{}]", c[0], c[1], c[2])
        })
        .collect();
    let title: String = cfg
        .title
        .chars()
        .filter(|c| !matches!(c, '<' | '>' | '&' | '"'))
        .collect();
    Ok(PAGE
        .replace("__TITLE__", &title)
        .replace("__LAYERS__", &js_layers)
        .replace("__STOPS__", &format!("[{}]", stops.join(",")))
        .replace("__RANGE__", &format!("{}", cfg.error_range_mm))
        .replace("__RADIUS__", &format!("{radius}"))
        .replace("__SCAN_LIT__", &format!("{SCAN_SHADING}")))
}

/// The page; `__NAME__` placeholders are filled by [`viewer_html`].
const PAGE: &str = r#"<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>__TITLE__</title>
<style>
html,body{margin:0;height:100%;background:#1e1e22;color:#ddd;font:14px sans-serif;overflow:hidden}
#c{width:100%;height:100%;display:block;cursor:grab}
#ui{position:absolute;top:8px;left:8px;background:rgba(0,0,0,.55);padding:6px 8px;border-radius:4px}
#ui button{margin:2px;background:#333;color:#ddd;border:1px solid #666;border-radius:3px;padding:3px 7px;cursor:pointer}
#ui button.on{background:#4a6fa5;color:#fff}
#legend{position:absolute;bottom:12px;left:12px;background:rgba(0,0,0,.55);padding:6px 8px;border-radius:4px;display:none}
#bar{width:240px;height:14px}
#lab{display:flex;justify-content:space-between;width:240px}
#msg{position:absolute;top:40%;width:100%;text-align:center;display:none}
</style></head><body>
<canvas id="c"></canvas>
<div id="ui"><b>__TITLE__</b><br><span id="layers"></span><br>
<button id="col">colour: shaded</button> <button id="reset">reset view</button>
<br><small>drag: rotate · wheel: zoom · shift-drag: pan</small></div>
<div id="legend">signed error to the truth (mm)<br><canvas id="bar" width="240" height="14"></canvas>
<div id="lab"><span id="lmin"></span><span>0</span><span id="lmax"></span></div></div>
<div id="msg">WebGL is not available in this browser.</div>
<script>
"use strict";
const LAYERS=__LAYERS__, STOPS=__STOPS__, RANGE=__RANGE__, RADIUS=__RADIUS__, SCAN_LIT=__SCAN_LIT__;
function dec(s,T){if(!s)return null;const b=atob(s),u=new Uint8Array(b.length);for(let i=0;i<b.length;i++)u[i]=b.charCodeAt(i);return new T(u.buffer);}
function cmap(t){t=Math.min(1,Math.max(0,t))*(STOPS.length-1);const i=Math.min(STOPS.length-2,Math.floor(t)),f=t-i,a=STOPS[i],b=STOPS[i+1];return [0,1,2].map(k=>(a[k]+f*(b[k]-a[k]))/255);}
const cv=document.getElementById("c");
const gl=cv.getContext("webgl",{antialias:true,preserveDrawingBuffer:true});
let mode="shaded";
if(!gl){document.getElementById("msg").style.display="block";}
else{
const ext=gl.getExtension("OES_element_index_uint");
const vs=`attribute vec3 p;attribute vec3 n;attribute vec3 c;uniform mat4 mv;uniform mat4 pr;uniform float ps;varying vec3 vn;varying vec3 vc;
void main(){vn=(mv*vec4(n,0.)).xyz;vc=c;gl_Position=pr*mv*vec4(p,1.);gl_PointSize=ps;}`;
const fs=`precision mediump float;varying vec3 vn;varying vec3 vc;uniform float lit;
void main(){vec3 n=normalize(vn+vec3(0.,0.,1e-6));if(n.z<0.)n=-n;float s=mix(1.,.2+.8*max(dot(n,normalize(vec3(.3,.5,1.))),0.),lit);gl_FragColor=vec4(vc*s,1.);}`;
function sh(t,s){const o=gl.createShader(t);gl.shaderSource(o,s);gl.compileShader(o);return o;}
const prog=gl.createProgram();gl.attachShader(prog,sh(gl.VERTEX_SHADER,vs));gl.attachShader(prog,sh(gl.FRAGMENT_SHADER,fs));gl.linkProgram(prog);gl.useProgram(prog);
const loc={p:gl.getAttribLocation(prog,"p"),n:gl.getAttribLocation(prog,"n"),c:gl.getAttribLocation(prog,"c"),mv:gl.getUniformLocation(prog,"mv"),pr:gl.getUniformLocation(prog,"pr"),ps:gl.getUniformLocation(prog,"ps"),lit:gl.getUniformLocation(prog,"lit")};
function buf(d,t){const b=gl.createBuffer();gl.bindBuffer(t||gl.ARRAY_BUFFER,b);gl.bufferData(t||gl.ARRAY_BUFFER,d,gl.STATIC_DRAW);return b;}
const layers=LAYERS.map((L,k)=>{const pos=dec(L.pos,Float32Array),nrm=dec(L.nrm,Float32Array),err=dec(L.err,Float32Array),col=dec(L.col,Uint8Array),idx=dec(L.idx,Uint32Array);const n=pos.length/3;
 const grey=new Float32Array(n*3).fill(.82),ec=new Float32Array(n*3),sc=col?new Float32Array(n*3):null;
 for(let i=0;i<n;i++){const e=err?err[i]:NaN;const c=isNaN(e)?[.82,.82,.82]:cmap((e/RANGE+1)/2);ec.set(c,3*i);}
 if(col)for(let i=0;i<n*3;i++)sc[i]=col[i]/255;
 return {name:L.name,kind:L.kind,n:n,hasErr:!!err,hasCol:!!col,on:k===0,p:buf(pos),nr:buf(nrm),grey:buf(grey),ec:buf(ec),sc:col?buf(sc):null,idx:idx&&idx.length?buf(idx,gl.ELEMENT_ARRAY_BUFFER):null,count:idx?idx.length:0};});
const span=document.getElementById("layers");
layers.forEach(L=>{const b=document.createElement("button");b.textContent=L.name;b.className=L.on?"on":"";b.onclick=()=>{L.on=!L.on;b.className=L.on?"on":"";draw();};span.appendChild(b);});
const modes=["shaded"];if(layers.some(L=>L.hasCol))modes.push("scan");if(layers.some(L=>L.hasErr))modes.push("error");
const colB=document.getElementById("col");
if(modes.length<2)colB.style.display="none";
function setMode(m){mode=m;colB.textContent="colour: "+m;document.getElementById("legend").style.display=m==="error"?"block":"none";draw();}
colB.onclick=()=>setMode(modes[(modes.indexOf(mode)+1)%modes.length]);
const bar=document.getElementById("bar").getContext("2d");for(let x=0;x<240;x++){const c=cmap(x/239);bar.fillStyle=`rgb(${c.map(v=>Math.round(v*255)).join(",")})`;bar.fillRect(x,0,1,14);}
document.getElementById("lmin").textContent="-"+RANGE;document.getElementById("lmax").textContent="+"+RANGE;
let yaw=0,pitch=0.35,dist=3*RADIUS,panX=0,panY=0;
function reset(){yaw=0;pitch=0.35;dist=3*RADIUS;panX=0;panY=0;draw();}
document.getElementById("reset").onclick=reset;
function mul(a,b){const o=new Float32Array(16);for(let i=0;i<4;i++)for(let j=0;j<4;j++){let s=0;for(let k=0;k<4;k++)s+=a[k*4+j]*b[i*4+k];o[i*4+j]=s;}return o;}
function draw(){const w=cv.clientWidth,h=cv.clientHeight;if(cv.width!==w||cv.height!==h){cv.width=w;cv.height=h;}
 gl.viewport(0,0,w,h);gl.clearColor(.118,.118,.133,1);gl.clear(gl.COLOR_BUFFER_BIT|gl.DEPTH_BUFFER_BIT);gl.enable(gl.DEPTH_TEST);
 const cy=Math.cos(yaw),sy=Math.sin(yaw),cp=Math.cos(pitch),sp=Math.sin(pitch);
 // Camera frame of the scanner: x right, y down, z forward; the view looks along +z.
 const ry=[cy,0,-sy,0, 0,1,0,0, sy,0,cy,0, 0,0,0,1], rx=[1,0,0,0, 0,cp,sp,0, 0,-sp,cp,0, 0,0,0,1];
 const flip=[1,0,0,0, 0,-1,0,0, 0,0,-1,0, panX,panY,-dist,1];
 const mv=mul(flip,mul(rx,ry));
 const f=1/Math.tan(0.35),near=dist/100,far=dist*10,a=w/h;
 const pr=new Float32Array([f/a,0,0,0, 0,f,0,0, 0,0,(far+near)/(near-far),-1, 0,0,2*far*near/(near-far),0]);
 gl.uniformMatrix4fv(loc.mv,false,mv);gl.uniformMatrix4fv(loc.pr,false,pr);
 for(const L of layers){if(!L.on)continue;
  gl.bindBuffer(gl.ARRAY_BUFFER,L.p);gl.enableVertexAttribArray(loc.p);gl.vertexAttribPointer(loc.p,3,gl.FLOAT,false,0,0);
  gl.bindBuffer(gl.ARRAY_BUFFER,L.nr);gl.enableVertexAttribArray(loc.n);gl.vertexAttribPointer(loc.n,3,gl.FLOAT,false,0,0);
  const scan=mode==="scan"&&L.hasCol;
  gl.bindBuffer(gl.ARRAY_BUFFER,mode==="error"&&L.hasErr?L.ec:scan?L.sc:L.grey);gl.enableVertexAttribArray(loc.c);gl.vertexAttribPointer(loc.c,3,gl.FLOAT,false,0,0);
  // Scan colours already hold the scene's light: half the shading keeps the shape readable.
  gl.uniform1f(loc.lit,L.kind==="mesh"?(scan?SCAN_LIT:1):mode==="shaded"?1:0.6);gl.uniform1f(loc.ps,Math.max(1.5,Math.min(4,h/500*2)));
  if(L.kind==="mesh"&&L.idx&&ext){gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER,L.idx);gl.drawElements(gl.TRIANGLES,L.count,gl.UNSIGNED_INT,0);}
  else gl.drawArrays(gl.POINTS,0,L.n);}
 document.body.dataset.drawn=String(Date.now());}
let drag=null;
cv.onmousedown=e=>{drag={x:e.clientX,y:e.clientY,pan:e.shiftKey};cv.style.cursor="grabbing";};
window.onmouseup=()=>{drag=null;cv.style.cursor="grab";};
window.onmousemove=e=>{if(!drag)return;const dx=e.clientX-drag.x,dy=e.clientY-drag.y;drag.x=e.clientX;drag.y=e.clientY;
 if(drag.pan){panX+=dx*dist/cv.clientHeight;panY-=dy*dist/cv.clientHeight;}else{yaw+=dx*0.01;pitch=Math.max(-1.5,Math.min(1.5,pitch+dy*0.01));}draw();};
cv.addEventListener("wheel",e=>{e.preventDefault();dist*=Math.exp(e.deltaY*0.001);dist=Math.max(RADIUS*0.2,Math.min(RADIUS*50,dist));draw();},{passive:false});
window.onresize=draw;
const q=new URLSearchParams(location.search);if(modes.includes(q.get("colour")))setMode(q.get("colour"));
draw();
}
</script></body></html>
"#;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_shapes::sphere_mesh;

    #[test]
    fn base64_matches_the_standard() {
        assert_eq!(base64(b""), "");
        assert_eq!(base64(b"f"), "Zg==");
        assert_eq!(base64(b"fo"), "Zm8=");
        assert_eq!(base64(b"foo"), "Zm9v");
        assert_eq!(base64(b"foobar"), "Zm9vYmFy");
    }

    /// The page holds every vertex and index, loads nothing from elsewhere, and refuses an
    /// error array of the wrong length.
    #[test]
    fn page_is_self_contained() {
        let mesh = sphere_mesh(5.0, 4);
        let errs = vec![0.01f32; mesh.vertices.len()];
        let html = viewer_html(
            &[ViewerLayer::Mesh {
                name: "mesh",
                mesh: &mesh,
                errors_mm: Some(&errs),
                colours: None,
            }],
            &ViewerConfig::default(),
        )
        .unwrap();
        for banned in ["http:", "https:", "src=", "import "] {
            assert!(!html.contains(banned), "{banned}");
        }
        let pos = base64(&f32_bytes(mesh.vertices.iter().flat_map(|p| {
            let c = p - Point3::origin();
            [c.x as f32, c.y as f32, c.z as f32]
        })));
        assert!(pos.len() > 100);
        assert!(html.contains("kind:\"mesh\""));
        let bad = viewer_html(
            &[ViewerLayer::Mesh {
                name: "mesh",
                mesh: &mesh,
                errors_mm: Some(&errs[1..]),
                colours: None,
            }],
            &ViewerConfig::default(),
        );
        assert!(bad.is_err());
        assert!(viewer_html(&[], &ViewerConfig::default()).is_err());
    }

    /// Scan colours reach the page as base64 of their bytes (the mesh's all, the cloud's those
    /// of the points kept); colours not one per vertex are refused.
    #[test]
    fn scan_colours_are_embedded() {
        let mesh = sphere_mesh(5.0, 4);
        let colours: Vec<[u8; 3]> = (0..mesh.vertices.len())
            .map(|i| [(i % 256) as u8, 7, 200])
            .collect();
        let cloud = PointCloud::from_positions(vec![Point3::origin(), Point3::new(1.0, 0.0, 0.0)])
            .with_colors(vec![[1, 2, 3], [4, 5, 6]])
            .unwrap();
        let cfg = ViewerConfig {
            max_cloud_points: 1,
            ..ViewerConfig::default()
        };
        let html = viewer_html(
            &[
                ViewerLayer::Mesh {
                    name: "mesh",
                    mesh: &mesh,
                    errors_mm: None,
                    colours: Some(&colours),
                },
                ViewerLayer::Cloud {
                    name: "cloud",
                    cloud: &cloud,
                    errors_mm: None,
                },
            ],
            &cfg,
        )
        .unwrap();
        assert!(html.contains(&format!("col:\"{}\"", base64(&colours.concat()))));
        // One point of two kept: its colour only.
        assert!(html.contains(&format!("col:\"{}\"", base64(&[1, 2, 3]))));
        let e = viewer_html(
            &[ViewerLayer::Mesh {
                name: "mesh",
                mesh: &mesh,
                errors_mm: None,
                colours: Some(&colours[2..]),
            }],
            &cfg,
        )
        .unwrap_err();
        assert!(
            matches!(
                e,
                MeshError::AttributeLength {
                    attribute: "colours",
                    ..
                }
            ),
            "{e}"
        );
    }
}
