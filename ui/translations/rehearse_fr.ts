<?xml version="1.0" encoding="utf-8"?>
<!DOCTYPE TS>
<TS version="2.1" language="fr_FR">
<context>
    <name>AppearancePage</name>
    <message>
        <location filename="../src/pages/appearancepage.cpp" line="22"/>
        <source>Estimate the light and the organ&apos;s reflectance from the frame through the registered organ; the frame view then shows the organ re-shaded into the frame (F2 composited, F3 overlay, F4 3D).</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/appearancepage.cpp" line="28"/>
        <source>&amp;Background fill:</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/appearancepage.cpp" line="31"/>
        <source>How the frame behind the organ is filled, shown where the organ moves away. Navier-Stokes is the best trade-off measured on a real frame (BENCHMARKS.md).</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/appearancepage.cpp" line="33"/>
        <source>Navier-Stokes (default)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/appearancepage.cpp" line="34"/>
        <source>Telea</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/appearancepage.cpp" line="35"/>
        <source>Frequency-selective (slow)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/appearancepage.cpp" line="36"/>
        <source>Shift-map (slowest)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/appearancepage.cpp" line="42"/>
        <source>Estimate Appearance (F10)</source>
        <translation>Estimer l&apos;apparence (F10)</translation>
    </message>
    <message>
        <location filename="../src/pages/appearancepage.cpp" line="45"/>
        <source>Clear</source>
        <translation>Effacer</translation>
    </message>
    <message>
        <location filename="../src/pages/appearancepage.cpp" line="47"/>
        <source>Forget the estimate (Ctrl+Z brings it back)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/appearancepage.cpp" line="49"/>
        <source>Clear appearance</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/appearancepage.cpp" line="55"/>
        <source>Estimate Appearance (from any step)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/appearancepage.cpp" line="66"/>
        <source>Estimated light and reflectance</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/appearancepage.cpp" line="68"/>
        <source>x / R</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/appearancepage.cpp" line="68"/>
        <source>y / G</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/appearancepage.cpp" line="68"/>
        <source>z / B</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/appearancepage.cpp" line="69"/>
        <source>Light (mm)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/appearancepage.cpp" line="69"/>
        <source>k_d</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/appearancepage.cpp" line="69"/>
        <source>k_s</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/appearancepage.cpp" line="69"/>
        <source>σ / n</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/appearancepage.cpp" line="71"/>
        <source>Theta as DejaVu&apos;s Table 1: the light&apos;s position in the camera frame, the diffuse and specular reflectance per colour channel, the roughness σ and the scope&apos;s fall-off n (cos^n off its axis: the light&apos;s cone and the lens vignetting). * marks a channel the frame does not measure (clipped over its highlight).</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/appearancepage.cpp" line="102"/>
        <source>The frame without its specular highlights (I_D): what the diffuse part is fitted to</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/appearancepage.cpp" line="103"/>
        <source>The frame with the organ filled in (I_B): what shows where the organ moves away</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/appearancepage.cpp" line="104"/>
        <source>Diffuse image I_D</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/appearancepage.cpp" line="105"/>
        <source>Background I_B</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/appearancepage.cpp" line="106"/>
        <source>Left unexplained</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/appearancepage.cpp" line="108"/>
        <source>What Theta leaves of the frame on the organ, |frame - model| x 3: the organ&apos;s texture, specks, beads, and wherever the model does not hold (bright where it explains least)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/appearancepage.cpp" line="122"/>
        <source>(none)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/appearancepage.cpp" line="142"/>
        <location filename="../src/pages/appearancepage.cpp" line="144"/>
        <source>not determined</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/appearancepage.cpp" line="146"/>
        <source>n %1</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/appearancepage.cpp" line="148"/>
        <source>light %1 mm off lens</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/appearancepage.cpp" line="158"/>
        <source>No appearance yet: F10 estimates it from the frame and the organ as registered.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/appearancepage.cpp" line="159"/>
        <location filename="../src/pages/appearancepage.cpp" line="195"/>
        <source>The appearance needs %1.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/appearancepage.cpp" line="165"/>
        <source>%1: %2 levels, %3 ms</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/appearancepage.cpp" line="166"/>
        <source>Explains %1 % of the shading (smooth: %2 %); at rest %3 dB in the organ; %4 s.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/appearancepage.cpp" line="174"/>
        <source>%1 %2 %</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/appearancepage.cpp" line="175"/>
        <source> (not seen)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/appearancepage.cpp" line="176"/>
        <source>Left out: %1.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/appearancepage.cpp" line="183"/>
        <source>STALE: estimated at another pose, shape or frame; the composited view is off until it is estimated again (F10). %1</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/appearancepage.cpp" line="201"/>
        <source>Estimating... (Esc cancels)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/appearancepage.cpp" line="203"/>
        <source>Estimating the appearance...</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/appearancepage.cpp" line="214"/>
        <source>The organ moved while its appearance was estimated; estimate it again (F10).</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/appearancepage.cpp" line="219"/>
        <source>Estimate appearance</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/appearancepage.cpp" line="221"/>
        <source>Appearance: %1 (%2 s)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/appearancepage.cpp" line="226"/>
        <source>Cancelled; the case is unchanged.</source>
        <translation>Annulé ; le cas est inchangé.</translation>
    </message>
    <message>
        <location filename="../src/pages/appearancepage.cpp" line="233"/>
        <source>The appearance could not be estimated: %1</source>
        <translation type="unfinished"></translation>
    </message>
</context>
<context>
    <name>ContourPage</name>
    <message>
        <location filename="../src/pages/contourpage.cpp" line="25"/>
        <source>First frame</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/contourpage.cpp" line="26"/>
        <source>Second frame (the scope moved)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/contourpage.cpp" line="28"/>
        <source>Sketch the organ&apos;s outline on each frame: the fit uses both, and the camera&apos;s motion between them, to find the depth one outline cannot show.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/contourpage.cpp" line="30"/>
        <source>Sketch &amp;on</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/contourpage.cpp" line="53"/>
        <source>Middle button pans and the wheel zooms while drawing; Enter ends a click-by-click segment; in Edit, drag a point, Ctrl+click inserts, right-click deletes.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/contourpage.cpp" line="58"/>
        <source>Contour tool: %1</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/contourpage.cpp" line="63"/>
        <source>Snap to image edges</source>
        <translation>Accrocher aux bords de l&apos;image</translation>
    </message>
    <message>
        <location filename="../src/pages/contourpage.cpp" line="71"/>
        <source>Silhouette</source>
        <translation>Silhouette</translation>
    </message>
    <message>
        <location filename="../src/pages/contourpage.cpp" line="72"/>
        <source>Ridge</source>
        <translation>Crête</translation>
    </message>
    <message>
        <location filename="../src/pages/contourpage.cpp" line="73"/>
        <source>Ligament</source>
        <translation>Ligament</translation>
    </message>
    <message>
        <location filename="../src/pages/contourpage.cpp" line="74"/>
        <source>Silhouettes are drawn yellow, ridges orange, ligaments violet.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/contourpage.cpp" line="77"/>
        <source>New segments</source>
        <translation>Nouveaux segments</translation>
    </message>
    <message>
        <location filename="../src/pages/contourpage.cpp" line="82"/>
        <source>Resampling spacing</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/contourpage.cpp" line="85"/>
        <source> px</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/contourpage.cpp" line="86"/>
        <source>Resample</source>
        <translation>Rééchantillonner</translation>
    </message>
    <message>
        <location filename="../src/pages/contourpage.cpp" line="89"/>
        <source>Resample contour</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/contourpage.cpp" line="93"/>
        <source>Spacing</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/contourpage.cpp" line="98"/>
        <source>Smooth</source>
        <translation>Lisser</translation>
    </message>
    <message>
        <location filename="../src/pages/contourpage.cpp" line="100"/>
        <source>Smooth contour</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/contourpage.cpp" line="104"/>
        <source>Clear</source>
        <translation>Effacer</translation>
    </message>
    <message>
        <location filename="../src/pages/contourpage.cpp" line="106"/>
        <source>Clear contour</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/contourpage.cpp" line="113"/>
        <source>as the file says (P2ILF: raw)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/contourpage.cpp" line="114"/>
        <source>the raw frame</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/contourpage.cpp" line="115"/>
        <source>the undistorted frame</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/contourpage.cpp" line="116"/>
        <source>Where an imported contour&apos;s points were drawn. Points on the raw (distorted) frame are undistorted with the case&apos;s camera; P2ILF&apos;s contours are on the raw frame.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/contourpage.cpp" line="118"/>
        <source>Imported points on</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/contourpage.cpp" line="122"/>
        <source>Import...</source>
        <translation>Importer...</translation>
    </message>
    <message>
        <location filename="../src/pages/contourpage.cpp" line="124"/>
        <source>Import Contour</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/contourpage.cpp" line="124"/>
        <source>Contours (*.json)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/contourpage.cpp" line="127"/>
        <source>Export...</source>
        <translation>Exporter...</translation>
    </message>
    <message>
        <location filename="../src/pages/contourpage.cpp" line="129"/>
        <source>Rehearse contour, undistorted frame (*.json)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/contourpage.cpp" line="130"/>
        <source>P2ILF contour, raw frame (*.json)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/contourpage.cpp" line="132"/>
        <source>Export Contour</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/contourpage.cpp" line="155"/>
        <source>%1%2 segments, %3 points. %4</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/contourpage.cpp" line="156"/>
        <source>Second frame: </source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/contourpage.cpp" line="160"/>
        <source>The fit uses it with the first.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/contourpage.cpp" line="160"/>
        <source>Ready for fitting.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/contourpage.cpp" line="175"/>
        <source> Its points were on the raw frame and are undistorted with the case&apos;s camera.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/contourpage.cpp" line="177"/>
        <source> Its points are on the raw frame; the camera has no distortion, so they are used as they are.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/contourpage.cpp" line="183"/>
        <source>Import contour</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/contourpage.cpp" line="185"/>
        <source>Contour imported: %1 segments.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/contourpage.cpp" line="196"/>
        <source>Contour exported to %1 in P2ILF&apos;s layout, its points on the raw frame.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/contourpage.cpp" line="199"/>
        <source>Contour exported to %1.</source>
        <translation type="unfinished"></translation>
    </message>
</context>
<context>
    <name>FitPage</name>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="23"/>
        <source>Fit the organ onto the sketched contour: the silhouette is pulled onto it in the image plane and the elastic model (the case&apos;s material, see the Simulation panel, held by its ligaments) decides the rest. Afterwards keep the fit, or revert it (Ctrl+Z).</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="29"/>
        <source>Rigid pre-pass (refine the pose first)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="36"/>
        <source>&amp;Down (gravity):</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="39"/>
        <source>Which way gravity points in this view, if known: the fit then also finds how the organ sags towards or away from the camera, which the outline alone cannot show. Its size is still the fit&apos;s to find.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="41"/>
        <source>Not known</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="42"/>
        <source>Towards the image bottom</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="43"/>
        <source>Towards the image top</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="44"/>
        <source>Towards the image left</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="45"/>
        <source>Towards the image right</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="46"/>
        <source>Away from the camera</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="47"/>
        <source>Towards the camera</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="54"/>
        <source>Set which way is down</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="61"/>
        <source>&amp;Tolerance:</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="63"/>
        <location filename="../src/pages/fitpage.cpp" line="65"/>
        <source>Tolerance</source>
        <translation>Tolérance</translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="69"/>
        <source> mm</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="72"/>
        <source>A fit is determined only when its own bound on how far its surface may be from the truth is within this; otherwise it is shown as ambiguous, with what would decide it.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="79"/>
        <source>Pick Curve on Organ (K)</source>
        <translation>Choisir la courbe sur l&apos;organe (K)</translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="80"/>
        <source>Click along the ridge or ligament on the organ drawn over the frame; the sketched ridge or ligament nearest to the first click gets the curve. Enter ends, Backspace takes back a click.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="90"/>
        <source>Fit to Contour (F9)</source>
        <translation>Recaler sur le contour (F9)</translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="94"/>
        <source>Clear Fit</source>
        <translation>Effacer le recalage</translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="97"/>
        <source>Clear elastic fit</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="104"/>
        <source>Keep Fit</source>
        <translation>Garder le recalage</translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="106"/>
        <source>Revert Fit (Ctrl+Z)</source>
        <translation>Annuler le recalage (Ctrl+Z)</translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="108"/>
        <source>Back to the organ and pose before the fit; Redo brings the fit back.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="115"/>
        <source>Fit kept: %1
Uncertainty: %2.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="122"/>
        <source>Fit reverted: the organ and the pose are as before it (Ctrl+Shift+Z brings it back).</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="135"/>
        <source>Show where the organ &amp;may be</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="139"/>
        <source>After a fit: the organ&apos;s outline moved each way along the direction the fit is least sure of, as far as its bound (dashed): the organ may be anywhere between them.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="153"/>
        <source>Poses that fit the contour nearly as well as the fit: choose one to see the organ there</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="154"/>
        <source>Fit from It</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="156"/>
        <source>Put the organ at the chosen pose (one undo step) and fit from there without the rigid stage</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="175"/>
        <source>mean distance (px)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="179"/>
        <source>Contour to silhouette (px) against time (s)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="182"/>
        <source>s</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="185"/>
        <source>px</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="202"/>
        <source>The fit</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="205"/>
        <source>Alternative %1: %2 mm away, %3 px</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="215"/>
        <source>Use alternative pose</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="238"/>
        <source>Fit reverted</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="239"/>
        <source>No elastic fit yet: F9 fits the organ onto the contour.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="249"/>
        <source>(%1, %2, %3) in the camera frame</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="261"/>
        <source>No ridge or ligament sketched: the fit uses the silhouette alone.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="262"/>
        <source>Ridges and ligaments: %1 sketched, %2 with their curve on the organ (held by the fit).</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="273"/>
        <source>The fit needs %1.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="284"/>
        <source>Fitting... (Esc cancels)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="288"/>
        <source>Elastic fit...</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="314"/>
        <source> Second frame: %1; %2 features.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="323"/>
        <source>Cancelled; the case is unchanged.</source>
        <translation>Annulé ; le cas est inchangé.</translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="323"/>
        <location filename="../src/pages/fitpage.cpp" line="371"/>
        <source>The fit failed: %1</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="344"/>
        <source>where the organ may be (the fit&apos;s bound, %1 mm)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="345"/>
        <source>Elastic fit</source>
        <translation>Recalage élastique</translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="356"/>
        <source>AMBIGUOUS: %1</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="358"/>
        <source>%1 (%2 s). Keep it, or revert it (Ctrl+Z).
Uncertainty: %3.%4</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/fitpage.cpp" line="364"/>
        <source>Elastic fit: %1</source>
        <translation type="unfinished"></translation>
    </message>
</context>
<context>
    <name>FramePage</name>
    <message>
        <location filename="../src/pages/framepage.cpp" line="27"/>
        <source>Open Image or Video... (Ctrl+F)</source>
        <translation>Ouvrir une image ou une vidéo... (Ctrl+F)</translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="33"/>
        <source>Camera device number</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="35"/>
        <source>Live Camera</source>
        <translation>Caméra en direct</translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="37"/>
        <source>Device</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="41"/>
        <source>Video</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="53"/>
        <source>Previous frame (,)</source>
        <translation>Image précédente (,)</translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="58"/>
        <source>Next frame (.)</source>
        <translation>Image suivante (.)</translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="61"/>
        <location filename="../src/pages/framepage.cpp" line="211"/>
        <source>no video</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="66"/>
        <source>Use This Frame (Ctrl+Return)</source>
        <translation>Utiliser cette image (Ctrl+Entrée)</translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="73"/>
        <source>Second frame (the scope moved)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="80"/>
        <source>Use Shown Video Frame</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="82"/>
        <source>The video frame shown above, with the scope moved 1-2 cm sideways from the first frame</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="84"/>
        <source>Open Image...</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="87"/>
        <source>Open Second Frame</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="88"/>
        <source>Images (*.png *.jpg *.jpeg *.bmp *.tif *.tiff)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="91"/>
        <source>Clear</source>
        <translation>Effacer</translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="95"/>
        <source>Clear second frame</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="105"/>
        <source>Scope &amp;moved:</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="107"/>
        <source>How far the scope moved</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="111"/>
        <source> mm</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="112"/>
        <source>not known</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="115"/>
        <source>How far the scope moved between the two frames (a tracker&apos;s, a robot&apos;s, or the port&apos;s marks): the frames give the move&apos;s direction only, not its length.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="120"/>
        <source>Set how far the scope moved</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="127"/>
        <source>Camera intrinsics (px)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="129"/>
        <source>fx</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="129"/>
        <source>fy</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="129"/>
        <source>cx</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="129"/>
        <source>cy</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="140"/>
        <source>Edit intrinsics</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="150"/>
        <source>Distortion</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="151"/>
        <source>Load Calibration...</source>
        <translation>Charger l&apos;étalonnage...</translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="153"/>
        <source>Load Camera Calibration</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="154"/>
        <source>Calibrations (*.yaml *.yml *.xml *.json *.txt)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="157"/>
        <source>Default From Image Size</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="160"/>
        <source>Default intrinsics</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="177"/>
        <source>None: one outline leaves the organ&apos;s depth to its model; a second frame with the scope moved 1-2 cm sideways fixes it by parallax.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="179"/>
        <source>%1x%2, %3 outline segments sketched on it%4.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="183"/>
        <source>; say how far the scope moved</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="190"/>
        <source>Open Endoscope Image or Video</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="191"/>
        <source>Images and videos (*.png *.jpg *.jpeg *.bmp *.tif *.mp4 *.avi *.mkv *.mov)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="202"/>
        <location filename="../src/pages/framepage.cpp" line="384"/>
        <source>%1 is not a readable image; use PNG, JPEG, BMP or TIFF.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="219"/>
        <source>Opening video %1...</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="223"/>
        <source>%1 cannot be decoded as a video; check the file or convert it to MP4 (H.264).</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="232"/>
        <source>Video %1: %2 frames; scrub to pick the frame to work on.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="255"/>
        <source>Opening camera %1...</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="260"/>
        <source>Camera device %1 cannot be opened; check that it is connected and not in use.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="266"/>
        <source>live camera %1</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="291"/>
        <source>frame %1 of %2</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="297"/>
        <source>Frame %1 could not be decoded.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="323"/>
        <source>Pick frame %1</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="323"/>
        <source>Open frame</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="338"/>
        <source>Using frame %1 of the video.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="338"/>
        <source>Frame opened.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="339"/>
        <source> The contour sketched on the previous frame was removed: sketch it on this one (step 3), or Undo to go back to both.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="340"/>
        <source> The second frame, of another size, was removed.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="347"/>
        <source>Open the first frame before a second one.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="349"/>
        <source>The second frame is %1x%2 but the first is %3x%4: take it from the same video.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="361"/>
        <source>Set second frame</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="367"/>
        <source>%1 is the second frame: sketch the organ&apos;s outline on it (step 3, Second frame) and say how far the scope moved.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="375"/>
        <source>Open a video and show the frame to use as the second frame.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="378"/>
        <source>Frame %1 of the video</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="398"/>
        <source>The calibration is for %1x%2 images but the frame is %3x%4; choose the matching calibration.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="400"/>
        <source>Load calibration</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/framepage.cpp" line="405"/>
        <source>Calibration loaded from %1.</source>
        <translation type="unfinished"></translation>
    </message>
</context>
<context>
    <name>MeshPage</name>
    <message>
        <location filename="../src/pages/meshpage.cpp" line="34"/>
        <source>Import Mesh... (Ctrl+I)</source>
        <translation>Importer un maillage... (Ctrl+I)</translation>
    </message>
    <message>
        <location filename="../src/pages/meshpage.cpp" line="43"/>
        <source>Tetrahedra wanted when a surface is filled (size control)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/meshpage.cpp" line="44"/>
        <source>Target tetrahedra</source>
        <translation>Tétraèdres visés</translation>
    </message>
    <message>
        <location filename="../src/pages/meshpage.cpp" line="47"/>
        <source>Length unit of the file&apos;s coordinates</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/meshpage.cpp" line="48"/>
        <source>File unit</source>
        <translation>Unité du fichier</translation>
    </message>
    <message>
        <location filename="../src/pages/meshpage.cpp" line="50"/>
        <source>Labels (tick to show inner structures)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/meshpage.cpp" line="52"/>
        <source>Labels of the organ</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/meshpage.cpp" line="54"/>
        <source>Label</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/meshpage.cpp" line="54"/>
        <source>Kind</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/meshpage.cpp" line="54"/>
        <source>Elements</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/meshpage.cpp" line="61"/>
        <source>What the label&apos;s name says it is (a vessel&apos;s kind, a bile duct, a tumour, its margin, a ligament): what a cut through it is called in the rehearsal</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/meshpage.cpp" line="76"/>
        <source>Pick Attachments (H)</source>
        <translation>Choisir les attaches (H)</translation>
    </message>
    <message>
        <location filename="../src/pages/meshpage.cpp" line="77"/>
        <source>Click on the organ drawn over the frame where a ligament holds it: the surface nodes within the patch radius are attached; a click on attached nodes releases them. Each click is one undo step.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/meshpage.cpp" line="81"/>
        <source>Release All</source>
        <translation>Tout relâcher</translation>
    </message>
    <message>
        <location filename="../src/pages/meshpage.cpp" line="85"/>
        <source>Release all attachments</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/meshpage.cpp" line="95"/>
        <source> mm</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/meshpage.cpp" line="96"/>
        <source>Surface nodes within this distance of a click are attached or released together</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/meshpage.cpp" line="103"/>
        <source>Attachment patch radius</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/meshpage.cpp" line="131"/>
        <source>No ligament attachments: the organ is free (it falls in the simulation).</source>
        <translation type="unfinished"></translation>
    </message>
    <message numerus="yes">
        <location filename="../src/pages/meshpage.cpp" line="132"/>
        <source>Ligament attachments: %n node(s).</source>
        <translation type="unfinished">
            <numerusform></numerusform>
            <numerusform></numerusform>
        </translation>
    </message>
    <message>
        <location filename="../src/pages/meshpage.cpp" line="155"/>
        <source>Import Organ Mesh</source>
        <translation>Importer le maillage de l&apos;organe</translation>
    </message>
    <message>
        <location filename="../src/pages/meshpage.cpp" line="156"/>
        <source>Meshes and segmentations (*.msh *.vtk *.vtu *.mesh *.obj *.stl *.ply *.off *.gltf *.glb *.nrrd *.nhdr *.nii *.nii.gz *.mha *.mhd *.inr *.inr.gz);;Meshes (*.msh *.vtk *.vtu *.mesh *.obj *.stl *.ply *.off *.gltf *.glb);;Segmentations: label images (*.nrrd *.nhdr *.nii *.nii.gz *.mha *.mhd *.inr *.inr.gz)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/meshpage.cpp" line="169"/>
        <source>Importing %1...</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/meshpage.cpp" line="193"/>
        <source>Import segmentation</source>
        <translation>Importer une segmentation</translation>
    </message>
    <message>
        <location filename="../src/pages/meshpage.cpp" line="197"/>
        <source>Imported the segmentation %1: %2 tetrahedra in %3 labelled parts</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/meshpage.cpp" line="223"/>
        <source>With the file unit %1 this organ would measure %2 mm across; organs measure 10 to 1000 mm.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/meshpage.cpp" line="225"/>
        <source> Check the file.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/meshpage.cpp" line="226"/>
        <source> The file is probably in %1 (%2 mm across): choose that file unit and import again.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/meshpage.cpp" line="251"/>
        <source>Import mesh</source>
        <translation>Importer un maillage</translation>
    </message>
    <message>
        <location filename="../src/pages/meshpage.cpp" line="256"/>
        <source>Imported %1: %2 tetrahedra, drawn through its own surface (%3 triangles)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/meshpage.cpp" line="260"/>
        <source>Imported %1: %2 tetrahedra</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/meshpage.cpp" line="265"/>
        <source>Import cancelled; the case is unchanged.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/meshpage.cpp" line="266"/>
        <source>cancelled</source>
        <translation type="unfinished"></translation>
    </message>
</context>
<context>
    <name>QObject</name>
    <message>
        <location filename="../src/pages/rigidpage.cpp" line="28"/>
        <source>Move the organ left %1</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rigidpage.cpp" line="29"/>
        <source>Move the organ right %1</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rigidpage.cpp" line="30"/>
        <source>Move the organ up %1</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rigidpage.cpp" line="31"/>
        <source>Move the organ down %1</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rigidpage.cpp" line="32"/>
        <source>Move the organ away from the camera %1</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rigidpage.cpp" line="33"/>
        <source>Move the organ towards the camera %1</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rigidpage.cpp" line="34"/>
        <source>Turn the organ about the camera&apos;s x axis %1</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rigidpage.cpp" line="35"/>
        <source>Turn the organ about the camera&apos;s x axis back %1</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rigidpage.cpp" line="36"/>
        <source>Turn the organ about the camera&apos;s y axis %1</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rigidpage.cpp" line="37"/>
        <source>Turn the organ about the camera&apos;s y axis back %1</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rigidpage.cpp" line="38"/>
        <source>Turn the organ about the camera&apos;s z axis %1</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rigidpage.cpp" line="39"/>
        <source>Turn the organ about the camera&apos;s z axis back %1</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationpanel.cpp" line="481"/>
        <source>Warning: 1 element inside out (magenta; volume ratio %1): the shape there is not tissue.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationpanel.cpp" line="483"/>
        <source>Warning: %1 elements inside out (magenta; smallest volume ratio %2): the shape there is not tissue.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationpanel.cpp" line="488"/>
        <source>Warning: the step was held back to keep elements from turning inside out (relative residual %1).</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/tools/attachmenttool.cpp" line="41"/>
        <source>Attachments are picked on the organ drawn over the frame: open a frame (step 2) first.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/tools/attachmenttool.cpp" line="46"/>
        <source>Click on the organ drawn over the frame where a ligament holds it.</source>
        <translation type="unfinished"></translation>
    </message>
    <message numerus="yes">
        <location filename="../src/tools/attachmenttool.cpp" line="69"/>
        <source>Release %n attachment node(s)</source>
        <translation type="unfinished">
            <numerusform></numerusform>
            <numerusform></numerusform>
        </translation>
    </message>
    <message numerus="yes">
        <location filename="../src/tools/attachmenttool.cpp" line="70"/>
        <source>Attach %n node(s)</source>
        <translation type="unfinished">
            <numerusform></numerusform>
            <numerusform></numerusform>
        </translation>
    </message>
    <message>
        <location filename="../src/tools/cauterytool.cpp" line="23"/>
        <source>The cautery hook works on the organ placed over the frame: place it first (step 4).</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/tools/cauterytool.cpp" line="28"/>
        <source>Press on the organ to apply energy there.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/tools/cauterytool.cpp" line="36"/>
        <source>Energy on: drag along the organ to burn a line, release to stop.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/tools/cauterytool.cpp" line="52"/>
        <source>Energy off.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/tools/cliptool.cpp" line="23"/>
        <source>The clip applier works on the organ placed over the frame: place it first (step 4).</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/tools/cliptool.cpp" line="28"/>
        <source>Click on the organ, over the vessel to clip.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/tools/cliptool.cpp" line="60"/>
        <source>Clip aimed at the %1 %2 mm below the surface (U: clip applier; R: grasper, B: scissors).</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/tools/cliptool.cpp" line="61"/>
        <source>vessel</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/tools/cliptool.cpp" line="63"/>
        <source>No vessel under the cursor within 25 mm: the clip was aimed at the tissue there.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/tools/drawtool.cpp" line="54"/>
        <location filename="../src/tools/drawtool.cpp" line="117"/>
        <source>Draw segment</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/tools/drawtool.cpp" line="54"/>
        <source>Add segment</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/tools/drawtool.cpp" line="115"/>
        <source>The frame changed while the stroke was snapping to its edges; draw it again.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/tools/drawtool.cpp" line="118"/>
        <source>No image edge was found along the stroke; it was kept as drawn.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/tools/drawtool.cpp" line="120"/>
        <source>Draw segment (snapped to edges)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/tools/drawtool.cpp" line="126"/>
        <source>Snapping the stroke to image edges...</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/tools/editpointstool.cpp" line="26"/>
        <source>Delete point</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/tools/editpointstool.cpp" line="39"/>
        <source>Move point</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/tools/editpointstool.cpp" line="81"/>
        <source>Insert point</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/tools/erasetool.cpp" line="51"/>
        <source>Erase</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/tools/gizmotool.cpp" line="56"/>
        <source>Nudge</source>
        <translation>Déplacement</translation>
    </message>
    <message>
        <location filename="../src/tools/gizmotool.cpp" line="114"/>
        <source>Move along camera X</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/tools/gizmotool.cpp" line="115"/>
        <source>Move along camera Y</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/tools/gizmotool.cpp" line="116"/>
        <source>Move along camera Z</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/tools/gizmotool.cpp" line="117"/>
        <source>Rotate about camera X</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/tools/gizmotool.cpp" line="118"/>
        <source>Rotate about camera Y</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/tools/gizmotool.cpp" line="123"/>
        <source>Rotate about camera Z</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/tools/grasptool.cpp" line="48"/>
        <source>Released.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/tools/grasptool.cpp" line="66"/>
        <source>The jaws still hold: drag to pull on, Space or a click lets go.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/tools/grasptool.cpp" line="68"/>
        <source>The grasper keeps its hold while you cut (R, then Space, lets go).</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/tools/grasptool.cpp" line="94"/>
        <source>The grasper works on the organ placed over the frame: place it first (step 4).</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/tools/grasptool.cpp" line="102"/>
        <source>Press on the organ to grasp it.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/tools/grasptool.cpp" line="114"/>
        <source>Grasped: drag to pull, release to let go.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/tools/organcurvetool.cpp" line="38"/>
        <location filename="../src/tools/organcurvetool.cpp" line="94"/>
        <source>Pick organ curve</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/tools/organcurvetool.cpp" line="43"/>
        <source>Organ curve done; the fit (F9) holds it onto the sketched curve.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/tools/organcurvetool.cpp" line="58"/>
        <source>Click on the organ drawn over the frame, along the ridge or ligament.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/tools/organcurvetool.cpp" line="75"/>
        <source>Sketch the ridge or ligament on the frame first (step 3, new segments: Ridge or Ligament).</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/tools/organcurvetool.cpp" line="95"/>
        <source>%1: %2 nodes on the organ. Click on along it; Backspace takes back a click, Enter or a double click ends.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/tools/scissorstool.cpp" line="25"/>
        <source>The scissors work on the organ placed over the frame: place it first (step 4).</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/tools/scissorstool.cpp" line="30"/>
        <source>Press on the organ to start the cut.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/tools/scissorstool.cpp" line="39"/>
        <source>Cutting: drag across the organ, release to stop (wheel: deeper or shallower).</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/tools/scissorstool.cpp" line="51"/>
        <source>Cut ended.</source>
        <translation type="unfinished"></translation>
    </message>
</context>
<context>
    <name>RehearsePage</name>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="27"/>
        <source>Rehearse the gesture on the registered organ: with the grasper, press on the organ to close the jaws there, drag to pull it, release to let go (Space closes them at the cursor and keeps them closed); with the scissors, press on the organ and drag across it to cut, release to stop; with the clip applier, click over a vessel to clip it (a cut vessel bleeds unless a clip lies behind the cut); with the cautery hook, press and drag to burn a line (burnt tissue stiffens, whitens and is cut without bleeding). Take the scissors or the clip applier while the jaws hold and they keep the traction, which opens the incision. The wheel moves the instrument&apos;s tip along the view ray while you hold it. The simulation runs while you work (Simulation panel: material, ligaments); the view shows it composited into the frame once the appearance is estimated (step 6), cut faces in preset interior colours; the overlay (F3) shows cut tissue in dark red.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="43"/>
        <source>Grasper (R)</source>
        <translation>Pince (R)</translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="43"/>
        <source>Press on the organ to grasp it, drag to pull, release to let go</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="48"/>
        <source>Scissors (B)</source>
        <translation>Ciseaux (B)</translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="48"/>
        <source>Press on the organ and drag across it to cut, release to stop</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="52"/>
        <source>Clip applier (U)</source>
        <translation>Pose-clip (U)</translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="53"/>
        <source>Click on the organ over a vessel to close a clip across it; cut between two clips and the vessel does not bleed</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="58"/>
        <source>Cautery hook (J)</source>
        <translation>Crochet coagulateur (J)</translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="59"/>
        <source>Press on the organ to apply energy, drag to burn a line (the tissue whitens and stiffens; a cut along it does not bleed), release to stop</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="67"/>
        <source>Trainee</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="69"/>
        <source>trainee (name or id)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="70"/>
        <source>Who rehearses: recorded with the session</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="71"/>
        <location filename="../src/pages/rehearsepage.cpp" line="313"/>
        <source>Record</source>
        <translation>Enregistrer</translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="74"/>
        <source>Record the rehearsal into the case file (Ctrl+R): the simulation starts again from rest; press again to stop</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="76"/>
        <source>Review...</source>
        <translation>Revoir...</translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="78"/>
        <source>Replay and review the sessions recorded in this case (Ctrl+Shift+R)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="90"/>
        <source>Recording is not available here.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="121"/>
        <source>Tool force (N), last 5 s</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="124"/>
        <source>s</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="127"/>
        <source>N</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="162"/>
        <source>Tool-force loop: no simulation running.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="191"/>
        <source> · precomputed %1 ms/step, exact</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="194"/>
        <source> · hybrid %1 ms/step, exact</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="197"/>
        <source> · FFD %1 ms/step, Hertz</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="200"/>
        <source> · FEM %1 ms/step, extrapolated</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="203"/>
        <source>Force loop %1 Hz (p99 %2 ms%3)%4</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="206"/>
        <source>, real-time</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="209"/>
        <source>%1
The tool force computed at %2 Hz on its own thread (period: median %3 ms, 99th percentile %4 ms). %5</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="215"/>
        <source>The %1 model&apos;s stiffness at the instrument is exact (linear and static): between its steps the loop renders the model&apos;s own force.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="217"/>
        <source>hybrid</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="217"/>
        <source>precomputed</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="219"/>
        <source>Between the FFD model&apos;s steps the loop follows Hertz&apos;s law along the pull by its slope (the force itself is Hertz&apos;s law at each step).</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="221"/>
        <source>Between the FEM&apos;s steps the loop extrapolates the last step&apos;s force with its stiffness (a guess until the next step).</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="227"/>
        <source>Place the organ over the frame first (step 4).</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="228"/>
        <source>Place the organ</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="230"/>
        <source>Pick the grasper (R), the scissors (B), the clip applier (U) or the cautery hook (J) and press on the organ.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="257"/>
        <source>Cutting: %1 elements, %2 nodes.</source>
        <translation type="unfinished"></translation>
    </message>
    <message numerus="yes">
        <location filename="../src/pages/rehearsepage.cpp" line="259"/>
        <source>Holding %n node(s) of tissue.</source>
        <translation type="unfinished">
            <numerusform></numerusform>
            <numerusform></numerusform>
        </translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="261"/>
        <source>The jaws are closed on nothing.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="263"/>
        <source>Released: the tissue relaxes.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="264"/>
        <source>Cutting</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="265"/>
        <source>Cut: %1 elements, %2 nodes.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="267"/>
        <source>   slips: %1</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="268"/>
        <source>   cuts: %1</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="269"/>
        <source>   vessels cut: %1</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="270"/>
        <source>   TORN: %1</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="271"/>
        <source>   clips: %1</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="272"/>
        <source>   ENERGY ON</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="277"/>
        <source>   blood lost: %1 mL%2</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="279"/>
        <source> (bleeding %1 mL/s)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="284"/>
        <source> (jaws %1 N, shaft %2 N)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="291"/>
        <source> — Hertz&apos;s contact law (the FFD model is geometric: no equilibrium force)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="293"/>
        <source> — step not converged (relative residual %1): not the equilibrium force</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="295"/>
        <source>Tool force %1 N%2%3</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rehearsepage.cpp" line="313"/>
        <source>Stop recording</source>
        <translation>Arrêter l&apos;enregistrement</translation>
    </message>
</context>
<context>
    <name>RigidPage</name>
    <message>
        <location filename="../src/pages/rigidpage.cpp" line="48"/>
        <source>Gizmo (G)</source>
        <translation>Manipulateur (G)</translation>
    </message>
    <message>
        <location filename="../src/pages/rigidpage.cpp" line="49"/>
        <source>Drag X, Y, Z to move along the camera axes, rX, rY, rZ to turn about them through the organ&apos;s centre. Keys: arrows and PgUp/PgDn move 1 mm, W/S A/D Q/E turn 1 degree; Shift for 10 mm / 5 degrees.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rigidpage.cpp" line="54"/>
        <source>Pose (camera frame; R = Rz Ry Rx)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rigidpage.cpp" line="55"/>
        <source>Model to camera: translation in mm; rotation as angles about the camera&apos;s Z, Y and X axes in degrees, applied X first (R = Rz(rz) Ry(ry) Rx(rx)). Camera axes: x right, y down, z forward.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rigidpage.cpp" line="79"/>
        <source>Edit pose fields</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rigidpage.cpp" line="88"/>
        <source>Reset to Automatic Placement</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rigidpage.cpp" line="90"/>
        <source>Reset pose</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rigidpage.cpp" line="97"/>
        <source>Load Pose...</source>
        <translation>Charger une pose...</translation>
    </message>
    <message>
        <location filename="../src/pages/rigidpage.cpp" line="99"/>
        <source>A pose file: JSON {&quot;R&quot;: [[...]], &quot;t&quot;: [...], &quot;unit&quot;: &quot;m&quot;} or a 4x4 text matrix in the mesh&apos;s unit</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rigidpage.cpp" line="101"/>
        <source>Load Pose</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rigidpage.cpp" line="101"/>
        <source>Poses (*.json *.txt)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rigidpage.cpp" line="105"/>
        <source>Landmark pairs (mesh point, then image point)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rigidpage.cpp" line="107"/>
        <source>Pick Landmarks (L)</source>
        <translation>Choisir des repères (L)</translation>
    </message>
    <message>
        <location filename="../src/pages/rigidpage.cpp" line="107"/>
        <source>Click a point on the organ, then where it is in the frame; 4 pairs or more</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rigidpage.cpp" line="110"/>
        <source>Landmark pairs</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rigidpage.cpp" line="114"/>
        <source>Solve Pose</source>
        <translation>Calculer la pose</translation>
    </message>
    <message>
        <location filename="../src/pages/rigidpage.cpp" line="117"/>
        <source>Clear</source>
        <translation>Effacer</translation>
    </message>
    <message>
        <location filename="../src/pages/rigidpage.cpp" line="119"/>
        <source>Clear landmarks</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rigidpage.cpp" line="144"/>
        <source>Nudge</source>
        <translation>Déplacement</translation>
    </message>
    <message>
        <location filename="../src/pages/rigidpage.cpp" line="157"/>
        <source>Landmark on the organ</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rigidpage.cpp" line="158"/>
        <source>Landmark %1 on the organ; now click where it is in the frame.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rigidpage.cpp" line="165"/>
        <source>Landmark in the frame</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rigidpage.cpp" line="166"/>
        <source>%1 landmark pairs; click the organ for the next, or solve (4 or more).</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rigidpage.cpp" line="188"/>
        <source>click the frame</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rigidpage.cpp" line="213"/>
        <source>Load pose</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rigidpage.cpp" line="218"/>
        <source>Pose loaded from %1.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rigidpage.cpp" line="234"/>
        <source>Pick at least 4 landmark pairs first.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rigidpage.cpp" line="239"/>
        <source>The landmarks do not determine a pose; spread them over the organ and try again.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rigidpage.cpp" line="244"/>
        <source>Pose from landmarks</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rigidpage.cpp" line="250"/>
        <source>Pose from %1 landmark pairs: reprojection RMS %2 px, but another pose fits nearly as well (%3 px): the landmarks do not decide; add pairs away from the others.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/pages/rigidpage.cpp" line="254"/>
        <source>Pose from %1 landmark pairs: reprojection RMS %2 px.</source>
        <translation type="unfinished"></translation>
    </message>
</context>
<context>
    <name>Step</name>
    <message>
        <location filename="../src/mainwindow.cpp" line="61"/>
        <source>Organ mesh</source>
        <translation>Maillage de l&apos;organe</translation>
    </message>
    <message>
        <location filename="../src/mainwindow.cpp" line="61"/>
        <source>Endoscope frame</source>
        <translation>Image endoscopique</translation>
    </message>
    <message>
        <location filename="../src/mainwindow.cpp" line="62"/>
        <source>Contour</source>
        <translation>Contour</translation>
    </message>
    <message>
        <location filename="../src/mainwindow.cpp" line="62"/>
        <source>Rigid alignment</source>
        <translation>Recalage rigide</translation>
    </message>
    <message>
        <location filename="../src/mainwindow.cpp" line="63"/>
        <source>Elastic fit</source>
        <translation>Recalage élastique</translation>
    </message>
    <message>
        <location filename="../src/mainwindow.cpp" line="63"/>
        <source>Appearance</source>
        <translation>Apparence</translation>
    </message>
    <message>
        <location filename="../src/mainwindow.cpp" line="64"/>
        <source>Rehearse</source>
        <translation>Répétition</translation>
    </message>
</context>
<context>
    <name>rehearse::ui</name>
    <message>
        <location filename="../src/caseinfo.cpp" line="20"/>
        <source>Case: %1
</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/caseinfo.cpp" line="21"/>
        <source>Mesh from: %1
</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/caseinfo.cpp" line="23"/>
        <source>! %1
</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/caseinfo.cpp" line="25"/>
        <source>Organ mesh
%1
</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/caseinfo.cpp" line="26"/>
        <source>surface triangles: %1
attachment nodes: %2

</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/caseinfo.cpp" line="28"/>
        <source>Camera
image: %1 x %2 px
fx %3  fy %4 px
cx %5  cy %6 px
distortion: %7 %8 %9 %10 %11

</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/caseinfo.cpp" line="32"/>
        <source>Pose (model to camera, %1)
%2
</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/caseinfo.cpp" line="32"/>
        <source>aligned</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/caseinfo.cpp" line="32"/>
        <source>automatic placement</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/caseinfo.cpp" line="33"/>
        <source>Elastic fit: %1

</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/caseinfo.cpp" line="36"/>
        <source>Appearance (estimated%1)
light: %2, %3, %4 mm
kd: %5 %6 %7
ks: %8 %9 %10
roughness: %11 rad
%12

</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/caseinfo.cpp" line="37"/>
        <source>, STALE: the organ or the frame changed since</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/caseinfo.cpp" line="43"/>
        <source>Ground-truth pose
%1</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/caseinfo.cpp" line="45"/>
        <source>
Light (ground truth)
position: %1, %2, %3 mm
kd: %4 %5 %6
ks: %7 %8 %9
roughness: %10 rad
</source>
        <translation type="unfinished"></translation>
    </message>
</context>
<context>
    <name>rehearse::ui::CaseDocument</name>
    <message>
        <location filename="../src/casedocument.cpp" line="78"/>
        <source>Saved %1</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/casedocument.cpp" line="146"/>
        <source>Nothing to save yet.</source>
        <translation type="unfinished"></translation>
    </message>
</context>
<context>
    <name>rehearse::ui::CohortWindow</name>
    <message>
        <location filename="../src/training/cohortwindow.cpp" line="40"/>
        <source>Training cohort - Rehearse</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/training/cohortwindow.cpp" line="42"/>
        <source>Cohort</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/training/cohortwindow.cpp" line="44"/>
        <source>Refresh</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/training/cohortwindow.cpp" line="45"/>
        <source>  plot </source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/training/cohortwindow.cpp" line="92"/>
        <source>Everyone (%1 sessions)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/training/cohortwindow.cpp" line="95"/>
        <source>%1 (%2)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/training/cohortwindow.cpp" line="95"/>
        <location filename="../src/training/cohortwindow.cpp" line="164"/>
        <source>(no name)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/training/cohortwindow.cpp" line="117"/>
        <source>session</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/training/cohortwindow.cpp" line="117"/>
        <source>trainee</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/training/cohortwindow.cpp" line="117"/>
        <source>started (UTC)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/training/cohortwindow.cpp" line="117"/>
        <source>case</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/training/cohortwindow.cpp" line="119"/>
        <source>replay verified</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/training/cohortwindow.cpp" line="138"/>
        <source>n/d</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/training/cohortwindow.cpp" line="142"/>
        <source>at publishing (machine not kept)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/training/cohortwindow.cpp" line="144"/>
        <source>Bit-exact replay holds for the same build on the same kind of machine; opening the session replays and verifies it here.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/training/cohortwindow.cpp" line="152"/>
        <source>%1 over each trainee&apos;s attempts</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/training/cohortwindow.cpp" line="154"/>
        <source>attempt</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/training/cohortwindow.cpp" line="181"/>
        <source>%1 sessions of %2 trainees in the training database</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/training/cohortwindow.cpp" line="221"/>
        <source>training database</source>
        <translation type="unfinished"></translation>
    </message>
</context>
<context>
    <name>rehearse::ui::Composition</name>
    <message>
        <location filename="../src/composition.cpp" line="20"/>
        <location filename="../src/composition.cpp" line="78"/>
        <source>no appearance estimated yet (step 6)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/composition.cpp" line="27"/>
        <location filename="../src/composition.cpp" line="91"/>
        <source>the appearance could not be applied: %1</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/composition.cpp" line="80"/>
        <source>the appearance was estimated at another pose, shape or frame; estimate it again (step 6, F10)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/composition.cpp" line="82"/>
        <location filename="../src/composition.cpp" line="95"/>
        <source>the appearance is being applied...</source>
        <translation type="unfinished"></translation>
    </message>
</context>
<context>
    <name>rehearse::ui::DeviceSteering</name>
    <message>
        <location filename="../src/devicesteering.cpp" line="35"/>
        <source>Connect &amp;3D Mouse</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/devicesteering.cpp" line="44"/>
        <source>A 3D mouse (through spacenavd) moves the instrument in step 7: push the cap to move it, turn it to pivot the shaft about the trocar; its left button works the instrument. The mouse works as before.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/devicesteering.cpp" line="67"/>
        <source>%1 connected: push the cap to move the instrument, turn it to pivot the shaft about the trocar, its left button works the instrument (step 7).</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/devicesteering.cpp" line="126"/>
        <source>The 3D mouse moves the instruments of step 7: take one (R grasper, B scissors, U clip applier, J cautery hook) on the placed organ.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/devicesteering.cpp" line="144"/>
        <source>Turning the cap about the shaft does nothing: the instrument&apos;s roll is not modelled (tilt it to pivot the shaft).</source>
        <translation type="unfinished"></translation>
    </message>
</context>
<context>
    <name>rehearse::ui::FrameView</name>
    <message>
        <location filename="../src/frameview.cpp" line="110"/>
        <source>Grasper</source>
        <translation>Pince</translation>
    </message>
    <message>
        <location filename="../src/frameview.cpp" line="111"/>
        <source>Scissors</source>
        <translation>Ciseaux</translation>
    </message>
    <message>
        <location filename="../src/frameview.cpp" line="112"/>
        <source>Clip applier</source>
        <translation>Pose-clip</translation>
    </message>
    <message>
        <location filename="../src/frameview.cpp" line="113"/>
        <source>Cautery hook</source>
        <translation>Crochet coagulateur</translation>
    </message>
    <message>
        <location filename="../src/frameview.cpp" line="148"/>
        <source>off the organ</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/frameview.cpp" line="151"/>
        <source>%1 mm before the tissue</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/frameview.cpp" line="151"/>
        <source>%1 mm into the tissue</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/frameview.cpp" line="162"/>
        <source>3D mouse · %1</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/frameview.cpp" line="192"/>
        <source>Click along the ridge or ligament on the organ drawn over the frame; the nearest sketched one gets the curve.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/frameview.cpp" line="286"/>
        <source>No frame yet: open an image or a video (step 2)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/frameview.cpp" line="388"/>
        <source>organ outline (O hides)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/frameview.cpp" line="389"/>
        <source>inner structures: colours as in step 1</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/frameview.cpp" line="397"/>
        <source>contour: %1</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/frameview.cpp" line="399"/>
        <source>landmark on the organ</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/frameview.cpp" line="400"/>
        <source>landmark in the frame</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/frameview.cpp" line="582"/>
        <source>Fit the frame to the view</source>
        <translation>Ajuster l&apos;image à la vue</translation>
    </message>
    <message>
        <location filename="../src/frameview.cpp" line="583"/>
        <source>Zoom in</source>
        <translation>Zoom avant</translation>
    </message>
    <message>
        <location filename="../src/frameview.cpp" line="584"/>
        <source>Zoom out</source>
        <translation>Zoom arrière</translation>
    </message>
    <message>
        <location filename="../src/frameview.cpp" line="585"/>
        <source>End the click-by-click segment or the curve being picked</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/frameview.cpp" line="586"/>
        <source>Abandon what the tool is drawing</source>
        <translation>Abandonner le tracé en cours</translation>
    </message>
    <message>
        <location filename="../src/frameview.cpp" line="587"/>
        <source>Take the last point of the curve on the organ back</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/frameview.cpp" line="588"/>
        <source>Grasper: close the jaws at the cursor, or open them</source>
        <translation type="unfinished"></translation>
    </message>
</context>
<context>
    <name>rehearse::ui::JobRunner</name>
    <message>
        <location filename="../src/jobrunner.cpp" line="22"/>
        <source>Another job is running; wait for it or cancel it (Esc).</source>
        <translation type="unfinished"></translation>
    </message>
</context>
<context>
    <name>rehearse::ui::MainWindow</name>
    <message>
        <location filename="../src/mainwindow.cpp" line="72"/>
        <source>Rehearse</source>
        <translation>Répétition</translation>
    </message>
    <message>
        <location filename="../src/mainwindow.cpp" line="98"/>
        <source>u %1  v %2 px</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/mainwindow.cpp" line="119"/>
        <source>The simulation is not ready yet; the grasp did nothing (the organ needs a mesh and a pose).</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/mainwindow.cpp" line="132"/>
        <location filename="../src/mainwindow.cpp" line="532"/>
        <source>%1 - Rehearse</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/mainwindow.cpp" line="218"/>
        <source>   (next)</source>
        <translation>   (suivante)</translation>
    </message>
    <message>
        <location filename="../src/mainwindow.cpp" line="248"/>
        <source>Second frame</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/mainwindow.cpp" line="266"/>
        <source>Composited (OpenGL)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/mainwindow.cpp" line="266"/>
        <source>Composited</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/mainwindow.cpp" line="267"/>
        <source>Overlay, not composited: %1</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/mainwindow.cpp" line="269"/>
        <source>Overlay</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/mainwindow.cpp" line="271"/>
        <source>3D</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/mainwindow.cpp" line="290"/>
        <source>The composited view needs the appearance: %1.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/mainwindow.cpp" line="300"/>
        <source>Second frame: the fit places the organ in it</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/mainwindow.cpp" line="302"/>
        <source>Contour to silhouette: mean %1 px, RMS %2 px, max %3 px</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/mainwindow.cpp" line="310"/>
        <source>Sketch a contour (step 3) to see its distance to the silhouette.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/mainwindow.cpp" line="331"/>
        <source>Saving %1...</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/mainwindow.cpp" line="348"/>
        <source>Save Case</source>
        <translation>Enregistrer le cas</translation>
    </message>
    <message>
        <location filename="../src/mainwindow.cpp" line="349"/>
        <source>Rehearse cases (*.rehearse)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/mainwindow.cpp" line="359"/>
        <source>Open Case</source>
        <translation>Ouvrir un cas</translation>
    </message>
    <message>
        <location filename="../src/mainwindow.cpp" line="360"/>
        <source>Rehearse cases (*.rehearse);;All files (*)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/mainwindow.cpp" line="368"/>
        <source>Recover case</source>
        <translation>Récupérer le cas</translation>
    </message>
    <message>
        <location filename="../src/mainwindow.cpp" line="369"/>
        <source>Rehearse did not close cleanly last time. Recover the case that was open then?</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/mainwindow.cpp" line="401"/>
        <source>%1: unknown file type.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/mainwindow.cpp" line="441"/>
        <source>Rehearse stopped unexpectedly last time%1; its report is kept on this machine, never sent: %2</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/mainwindow.cpp" line="442"/>
        <source> (%1)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/mainwindow.cpp" line="443"/>
        <source>Rehearse stopped unexpectedly</source>
        <translation>Rehearse s&apos;est arrêté inopinément</translation>
    </message>
    <message>
        <location filename="../src/mainwindow.cpp" line="444"/>
        <source>Rehearse stopped unexpectedly last time%1. The case open then was autosaved at most a minute before%2.

A report (version, what was running, the program&apos;s stack) is kept on this machine and never sent anywhere:
%3</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/mainwindow.cpp" line="447"/>
        <source>, during %1</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/mainwindow.cpp" line="448"/>
        <source> and is offered back</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/mainwindow.cpp" line="453"/>
        <source>Show Report</source>
        <translation>Afficher le rapport</translation>
    </message>
    <message>
        <location filename="../src/mainwindow.cpp" line="454"/>
        <source>Delete Report</source>
        <translation>Supprimer le rapport</translation>
    </message>
    <message>
        <location filename="../src/mainwindow.cpp" line="455"/>
        <source>Keep</source>
        <translation>Conserver</translation>
    </message>
    <message>
        <location filename="../src/mainwindow.cpp" line="473"/>
        <source>Crash report deleted.</source>
        <translation>Rapport de plantage supprimé.</translation>
    </message>
    <message>
        <location filename="../src/mainwindow.cpp" line="473"/>
        <source>Crash report kept: %1</source>
        <translation>Rapport de plantage conservé : %1</translation>
    </message>
    <message>
        <location filename="../src/mainwindow.cpp" line="506"/>
        <source>%1 s</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/mainwindow.cpp" line="507"/>
        <source>%1 · %2 s</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/mainwindow.cpp" line="511"/>
        <source>Generating the built-in phantom case...</source>
        <translation>Création du cas fantôme intégré...</translation>
    </message>
    <message>
        <location filename="../src/mainwindow.cpp" line="511"/>
        <source>Opening %1...</source>
        <translation>Ouverture de %1...</translation>
    </message>
    <message>
        <location filename="../src/mainwindow.cpp" line="533"/>
        <source>%1 loaded in %2 s</source>
        <translation>%1 chargé en %2 s</translation>
    </message>
    <message>
        <location filename="../src/mainwindow.cpp" line="534"/>
        <source> (%1 problems, see the Case panel)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/mainwindow_docks.cpp" line="73"/>
        <source>Case</source>
        <translation>Cas</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_docks.cpp" line="86"/>
        <location filename="../src/mainwindow_docks.cpp" line="231"/>
        <source>Messages</source>
        <translation>Messages</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_docks.cpp" line="96"/>
        <source>Organ 3D</source>
        <translation>Organe 3D</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_docks.cpp" line="101"/>
        <source>Views drawn on the CPU (--software).</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/mainwindow_docks.cpp" line="103"/>
        <source>No OpenGL 3.3 here: the views are drawn on the CPU.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/mainwindow_docks.cpp" line="107"/>
        <source>OpenGL here is a software rasteriser (%1): the views are drawn on the CPU, which is faster on it (&apos;rehearse --opengl&apos; uses OpenGL anyway).</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/mainwindow_docks.cpp" line="111"/>
        <source>Views drawn with OpenGL (%1).</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/mainwindow_docks.cpp" line="134"/>
        <source>Simulation</source>
        <translation>Simulation</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_docks.cpp" line="161"/>
        <source>Simulation (step %1): %2</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/mainwindow_docks.cpp" line="173"/>
        <source>The organ is cut: the composited view draws its cut mesh&apos;s boundary; cut faces take preset interior colours (parenchyma, a vessel&apos;s blood, other structures), not colours estimated from this frame.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/mainwindow_docks.cpp" line="204"/>
        <source>Edit material</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/mainwindow_docks.cpp" line="223"/>
        <location filename="../src/mainwindow_menus.cpp" line="123"/>
        <source>Cancel</source>
        <translation>Annuler</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_docks.cpp" line="224"/>
        <source>Cancel the running job (Esc)</source>
        <translation>Annuler la tâche en cours (Échap)</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_docks.cpp" line="232"/>
        <source>Every message of this session, whole (Ctrl+L)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/mainwindow_docks.cpp" line="258"/>
        <source>Workflow</source>
        <translation>Déroulement</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_docks.cpp" line="263"/>
        <source>Workflow steps</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/mainwindow_docks.cpp" line="271"/>
        <source>Alt+%1</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/mainwindow_docks.cpp" line="274"/>
        <source>Comes in a later version</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="58"/>
        <source>&amp;File</source>
        <translation>&amp;Fichier</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="59"/>
        <source>&amp;Open Case...</source>
        <translation>&amp;Ouvrir un cas...</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="61"/>
        <source>Open Case &amp;Folder...</source>
        <translation>Ouvrir un &amp;dossier de cas...</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="64"/>
        <source>Open Case Folder</source>
        <translation>Ouvrir un dossier de cas</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="70"/>
        <source>Open &amp;Recent</source>
        <translation>Ouverts &amp;récemment</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="72"/>
        <source>Open &amp;Built-in Phantom</source>
        <translation>Ouvrir le &amp;fantôme intégré</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="75"/>
        <source>&amp;Import Mesh...</source>
        <translation>&amp;Importer un maillage...</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="77"/>
        <source>Open &amp;Frame or Video...</source>
        <translation>Ouvrir une &amp;image ou une vidéo...</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="80"/>
        <source>&amp;Save</source>
        <translation>&amp;Enregistrer</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="82"/>
        <source>Save &amp;As...</source>
        <translation>Enregistrer &amp;sous...</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="84"/>
        <source>Recover &amp;Autosaved Case</source>
        <translation>Récupérer le cas &amp;sauvegardé automatiquement</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="87"/>
        <source>&amp;Quit</source>
        <translation>&amp;Quitter</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="89"/>
        <source>&amp;Edit</source>
        <translation>É&amp;dition</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="90"/>
        <source>&amp;Undo</source>
        <translation>&amp;Annuler</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="92"/>
        <source>&amp;Redo</source>
        <translation>&amp;Rétablir</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="100"/>
        <source>Undone: %1</source>
        <translation>Annulé : %1</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="104"/>
        <source>Redone: %1</source>
        <translation>Rétabli : %1</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="107"/>
        <source>&amp;Step</source>
        <translation>É&amp;tape</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="113"/>
        <source>Main</source>
        <translation>Principal</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="128"/>
        <source>&amp;Help</source>
        <translation>&amp;Aide</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="130"/>
        <source>&amp;Keyboard Shortcuts</source>
        <translation>&amp;Raccourcis clavier</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="133"/>
        <source>Keyboard Shortcuts</source>
        <translation>Raccourcis clavier</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="137"/>
        <source>Keyboard shortcuts</source>
        <translation>Raccourcis clavier</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="141"/>
        <source>Where</source>
        <translation>Où</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="141"/>
        <source>Keys</source>
        <translation>Touches</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="141"/>
        <source>What</source>
        <translation>Action</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="160"/>
        <source>User &amp;Guide</source>
        <translation>&amp;Guide de l&apos;utilisateur</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="166"/>
        <source>The user guide opens in the web browser: %1</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="168"/>
        <source>The user guide is not installed here (%1); build and install the package, or see the build folder&apos;s docs/guide/guide.html.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="172"/>
        <source>&amp;About Rehearse</source>
        <translation>À &amp;propos de Rehearse</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="174"/>
        <source>About Rehearse</source>
        <translation>À propos de Rehearse</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="175"/>
        <source>&lt;b&gt;Rehearse %1&lt;/b&gt; (%2)&lt;p&gt;Intra-operative surgical gesture rehearsal. It registers the pre-operative organ onto an endoscope frame (steps 1-5, with how sure the elastic fit is), estimates the organ&apos;s appearance and the light from the frame (step 6) and simulates the organ there, composited into the frame, where the grasper, scissors, clip applier and cautery hook act on it (step 7). Sessions are recorded for replay and review.&lt;/p&gt;</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="186"/>
        <source>&amp;View</source>
        <translation>&amp;Affichage</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="187"/>
        <source>Show &amp;Organ</source>
        <translation>Afficher l&apos;&amp;organe</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="194"/>
        <source>&amp;Fit Frame</source>
        <translation>&amp;Ajuster l&apos;image</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="197"/>
        <source>More Opaque Organ</source>
        <translation>Organe plus opaque</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="200"/>
        <source>More Transparent Organ</source>
        <translation>Organe plus transparent</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="206"/>
        <source>Organ &amp;Shaded</source>
        <translation>Organe &amp;ombré</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="207"/>
        <source>Organ &amp;Wireframe</source>
        <translation>Organe en &amp;fil de fer</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="208"/>
        <source>Organ Silhouette &amp;Only</source>
        <translation>&amp;Silhouette de l&apos;organe seule</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="223"/>
        <source>Next Organ Style</source>
        <translation>Style d&apos;organe suivant</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="226"/>
        <source>&amp;Legend</source>
        <translation>&amp;Légende</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="238"/>
        <source>&amp;Composited View</source>
        <translation>Vue &amp;composée</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="239"/>
        <source>The organ re-shaded into the frame, as estimated in step 6</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="240"/>
        <source>O&amp;verlay View</source>
        <translation>Vue en &amp;superposition</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="240"/>
        <source>The organ drawn over the frame</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="241"/>
        <source>&amp;3D View</source>
        <translation>Vue &amp;3D</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="241"/>
        <source>The organ alone, in 3D</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="254"/>
        <source>&amp;Navigate (pan and zoom)</source>
        <translation>&amp;Naviguer (déplacer et zoomer)</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="266"/>
        <source>Si&amp;mulate</source>
        <translation>Si&amp;mulation</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="271"/>
        <source>Show &amp;Simulation</source>
        <translation>Afficher la &amp;simulation</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="273"/>
        <source>&amp;Play / Pause</source>
        <translation>&amp;Lecture / pause</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="280"/>
        <source>Single S&amp;tep</source>
        <translation>Un &amp;pas</translation>
    </message>
    <message>
        <location filename="../src/mainwindow_menus.cpp" line="286"/>
        <source>&amp;Reset</source>
        <translation>&amp;Réinitialiser</translation>
    </message>
</context>
<context>
    <name>rehearse::ui::OrganGLView</name>
    <message>
        <location filename="../src/organglview.cpp" line="42"/>
        <source>Drag to turn the organ, wheel to zoom, double-click to reset (OpenGL)</source>
        <translation type="unfinished"></translation>
    </message>
</context>
<context>
    <name>rehearse::ui::OrganView</name>
    <message>
        <location filename="../src/organview.cpp" line="20"/>
        <source>Drag to turn the organ, wheel to zoom, double-click to reset</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/organview.cpp" line="92"/>
        <source>No organ mesh yet</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/organview.cpp" line="98"/>
        <source>%1 tets, %2 attachments</source>
        <translation type="unfinished"></translation>
    </message>
</context>
<context>
    <name>rehearse::ui::RecordingController</name>
    <message>
        <location filename="../src/recordingcontroller.cpp" line="48"/>
        <source>Start / Stop &amp;Recording</source>
        <translation>Démarrer / arrêter l&apos;&amp;enregistrement</translation>
    </message>
    <message>
        <location filename="../src/recordingcontroller.cpp" line="56"/>
        <source>Re&amp;view Recorded Rehearsals...</source>
        <translation>Re&amp;voir les répétitions enregistrées...</translation>
    </message>
    <message>
        <location filename="../src/recordingcontroller.cpp" line="58"/>
        <source>&amp;Incorrect-Action Rules...</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/recordingcontroller.cpp" line="60"/>
        <source>Which incorrect actions the trainer counts in this case&apos;s recorded rehearsals</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/recordingcontroller.cpp" line="68"/>
        <source>Save the case as a case file first (File &gt; Save As, .rehearse): the rehearsal is recorded into it.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/recordingcontroller.cpp" line="70"/>
        <source>Register the organ first (steps 4 and 5): the rehearsal runs on the registered organ.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/recordingcontroller.cpp" line="84"/>
        <source>The case&apos;s incorrect-action rules cannot be used: %1</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/recordingcontroller.cpp" line="88"/>
        <source>Recording%1 into %2 (the simulation started again from rest).</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/recordingcontroller.cpp" line="89"/>
        <source> %1</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/recordingcontroller.cpp" line="101"/>
        <source>Recorded session %1 in %2; review it with Ctrl+Shift+R.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/recordingcontroller.cpp" line="111"/>
        <source>The case has no file yet: save it, record a rehearsal (step 7), then review it.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/recordingcontroller.cpp" line="129"/>
        <source>Open a case first: the incorrect-action rules are the case&apos;s.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/recordingcontroller.cpp" line="144"/>
        <source>Incorrect-Action Rules - Rehearse</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/recordingcontroller.cpp" line="148"/>
        <source>What the trainer counts as an incorrect action in this case&apos;s rehearsals, each with its time on the review&apos;s timeline. Sessions keep the rules they were recorded with.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/recordingcontroller.cpp" line="160"/>
        <source>A vessel cut where no clip closes it (it bleeds)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/recordingcontroller.cpp" line="162"/>
        <source>Energy on a named structure (vessel, duct, tumour, ligament)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/recordingcontroller.cpp" line="163"/>
        <source>The tool&apos;s force over the limit for too long</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/recordingcontroller.cpp" line="174"/>
        <source> N</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/recordingcontroller.cpp" line="175"/>
        <source> s</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/recordingcontroller.cpp" line="176"/>
        <source>    limit</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/recordingcontroller.cpp" line="177"/>
        <source>    for at least</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/recordingcontroller.cpp" line="183"/>
        <source>Tissue torn (pulled past its material&apos;s tear strain)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/recordingcontroller.cpp" line="184"/>
        <source>A clip misplaced (on no vessel or duct, or not across it)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/recordingcontroller.cpp" line="188"/>
        <source>An instrument used outside the view (the case&apos;s camera, %1 x %2 px)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/recordingcontroller.cpp" line="191"/>
        <source>An instrument used outside the view (the case has no usable camera: not determined)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/recordingcontroller.cpp" line="221"/>
        <source>Incorrect-action rules</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/recordingcontroller.cpp" line="222"/>
        <source>The incorrect-action rules are set for the sessions recorded from now on.</source>
        <translation type="unfinished"></translation>
    </message>
</context>
<context>
    <name>rehearse::ui::ReviewWindow</name>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="167"/>
        <source>The case&apos;s thresholds cannot be read: %1</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="178"/>
        <source>Review - %1</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="180"/>
        <source>Review</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="182"/>
        <source> Session </source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="186"/>
        <source>  compare with </source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="191"/>
        <source>Play/Pause</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="192"/>
        <source>Play or pause (Space)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="193"/>
        <source>&lt;</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="193"/>
        <source>One step back (Left; Shift: ten)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="194"/>
        <source>&gt;</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="194"/>
        <source>One step on (Right; Shift: ten)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="195"/>
        <source>  speed </source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="203"/>
        <source>3D / Frame view</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="204"/>
        <source>Switch between the organ over the case&apos;s frame and a 3D view turned by dragging (V)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="205"/>
        <source>&amp;Review</source>
        <translation>&amp;Revue</translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="206"/>
        <source>Export &amp;Video...</source>
        <translation>Exporter la &amp;vidéo...</translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="207"/>
        <location filename="../src/review/reviewwindow.cpp" line="210"/>
        <source>Export video</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="207"/>
        <source>MP4 video (*.mp4)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="212"/>
        <source>Export &amp;Report (PDF)...</source>
        <translation>Exporter le &amp;rapport (PDF)...</translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="213"/>
        <location filename="../src/review/reviewwindow.cpp" line="216"/>
        <source>Export report</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="213"/>
        <source>PDF (*.pdf)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="218"/>
        <source>&amp;Thresholds...</source>
        <translation>&amp;Seuils...</translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="220"/>
        <location filename="../src/review/reviewwindow.cpp" line="225"/>
        <source>Thresholds</source>
        <translation>Seuils</translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="221"/>
        <source>A limit per metric, as JSON, e.g. {&quot;max_force_n&quot;: {&quot;max&quot;: 15}, &quot;economy_of_motion&quot;: {&quot;min&quot;: 0.8}}:</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="227"/>
        <source>&amp;Close</source>
        <translation>&amp;Fermer</translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="239"/>
        <source>Review window</source>
        <translation>Fenêtre de revue</translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="245"/>
        <source>Play or pause</source>
        <translation>Lecture ou pause</translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="246"/>
        <source>One step back</source>
        <translation>Un pas en arrière</translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="247"/>
        <source>One step on</source>
        <translation>Un pas en avant</translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="248"/>
        <source>Ten steps back</source>
        <translation>Dix pas en arrière</translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="249"/>
        <source>Ten steps on</source>
        <translation>Dix pas en avant</translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="256"/>
        <source>To the start</source>
        <translation>Au début</translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="263"/>
        <source>To the end</source>
        <translation>À la fin</translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="264"/>
        <source>The 3D view (drag to turn) or the frame</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="270"/>
        <source>%1 holds no recorded session: record one in step 7 (Rehearse) first.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="288"/>
        <source>holds no recorded session</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="300"/>
        <source>(none)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="306"/>
        <source>  (cut short)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="340"/>
        <source>metric</source>
        <translation>mesure</translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="340"/>
        <source>value</source>
        <translation>valeur</translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="340"/>
        <source>verdict</source>
        <translation>verdict</translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="360"/>
        <source>&lt;b&gt;Session %1&lt;/b&gt; - %2 - %3</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="377"/>
        <source>&lt;b&gt;Session %1&lt;/b&gt; - %2 - %3&lt;br&gt;&lt;span style=&quot;color:%4&quot;&gt;%5&lt;/span&gt;</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="383"/>
        <source> - replayed here, on %1</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="399"/>
        <source>Replaying session %1 for its timeline and metrics...</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="508"/>
        <source>Session %1 cannot be shown at step %2: %3</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="520"/>
        <source>session %1: step %2 of %3</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="522"/>
        <source>3D view (drag to turn)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="522"/>
        <source>over the case&apos;s frame</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="523"/>
        <source>%1  t = %2 s  %3  %4x  %5</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="523"/>
        <source>playing</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="523"/>
        <source>paused</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="535"/>
        <source>replay check</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="536"/>
        <source>%1 of %1 checksums match</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="537"/>
        <source>%1 of %2 checksums differ</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="537"/>
        <source>no checksum</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="540"/>
        <source>verified</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="540"/>
        <source>DOES NOT VERIFY</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="540"/>
        <source>not verified</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="549"/>
        <source>not determined</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="554"/>
        <source>%1 s: %2 (%3)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="557"/>
        <source>none under the session&apos;s rules</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="579"/>
        <source>The session is still being replayed; export when its timeline shows.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="587"/>
        <source>The export was cancelled; the partial file was left as it is.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="597"/>
        <source>Writing the video...</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="597"/>
        <source>Cancel</source>
        <translation>Annuler</translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="603"/>
        <source>Writing the video: frame %1 of %2</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="609"/>
        <source>Video of %1 frames written to %2</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="616"/>
        <source>Report written to %1</source>
        <translation type="unfinished"></translation>
    </message>
</context>
<context>
    <name>rehearse::ui::SimulationPanel</name>
    <message>
        <location filename="../src/simulationpanel.cpp"/>
        <source>The recording ended: the organ, its shape, pose or attachments changed (what was recorded is kept, complete).</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationpanel.cpp"/>
        <source>No organ volume to simulate; load or tetrahedralise a mesh first.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationpanel.cpp"/>
        <source>The recording did not start: %1</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationpanel.cpp"/>
        <source>Preset</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationpanel.cpp"/>
        <source>linear</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationpanel.cpp"/>
        <source>Material</source>
        <translation>Matériau</translation>
    </message>
    <message>
        <location filename="../src/simulationpanel.cpp"/>
        <source> %</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationpanel.cpp"/>
        <source>never</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationpanel.cpp"/>
        <source> ms</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationpanel.cpp"/>
        <location filename="../src/simulationpanel.cpp"/>
        <source> mm</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationpanel.cpp"/>
        <source>off</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationpanel.cpp"/>
        <source>Gravity</source>
        <translation>Gravité</translation>
    </message>
    <message>
        <location filename="../src/simulationpanel.cpp"/>
        <source>Stop the recording first: how the organ starts is part of the recorded session.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationpanel.cpp"/>
        <location filename="../src/simulationpanel.cpp"/>
        <source>Play</source>
        <translation>Lecture</translation>
    </message>
    <message>
        <location filename="../src/simulationpanel.cpp"/>
        <source>Play or pause the simulation (F5)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationpanel.cpp"/>
        <source>Step</source>
        <translation>Pas</translation>
    </message>
    <message>
        <location filename="../src/simulationpanel.cpp"/>
        <source>One time step (F6)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationpanel.cpp"/>
        <source>Reset</source>
        <translation>Réinitialiser</translation>
    </message>
    <message>
        <location filename="../src/simulationpanel.cpp"/>
        <source>Back to the rest shape (Shift+F5)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationpanel.cpp"/>
        <source>Save the case to a file first (File &gt; Save): the rehearsal is recorded into it.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationpanel.cpp"/>
        <source>No organ volume to rehearse on; load or tetrahedralise a mesh first.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationpanel.cpp"/>
        <source>Reset: recorded session %1 ended at step %2; the run from rest is recorded as a new session.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationpanel.cpp"/>
        <source>Reset: the run from rest is recorded as a new session.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationpanel.cpp"/>
        <source>The recording stopped (what was recorded is kept): %1</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationpanel.cpp"/>
        <source>Simulation: %1</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationpanel.cpp"/>
        <source>Simulation ready</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationpanel.cpp"/>
        <source>Simulation at rest (t = 0). This organ has no attachment nodes: it will fall freely under gravity.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationpanel.cpp"/>
        <source>Simulation at rest (t = 0)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationpanel.cpp"/>
        <source>t = 0. %1</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationpanel.cpp"/>
        <source> · %1 fps</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationpanel.cpp"/>
        <source>precomputed linear</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationpanel.cpp"/>
        <source>hybrid</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationpanel.cpp"/>
        <source>FFD</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationpanel.cpp"/>
        <source>%1 Newton</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationpanel.cpp"/>
        <source>t = %1 s · step %2 ms%3 · %4 · %5</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationpanel.cpp"/>
        <source>Pause</source>
        <translation type="unfinished"></translation>
    </message>
</context>
<context>
    <name>rehearse::ui::SimulationForm</name>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source>Materials of the DejaVu cases, on the current organ</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source>Preset</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source>linear</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source>corotational</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source>stvk</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source>neohookean</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source>neohookean-split</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source>Material</source>
        <translation>Matériau</translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source>Young&apos;s modulus</source>
        <translation>Module de Young</translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source> kPa</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source>Poisson&apos;s ratio</source>
        <translation>Coefficient de Poisson</translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source>Density</source>
        <translation>Densité</translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source> kg/m³</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source>
The presets set the tissue&apos;s density (liver 1,079 kg/m³); the organ&apos;s mass follows its volume.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source> %</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source>never</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source>Tears at strain</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source>
Pulled further than this, the tissue and its vessels tear (a torn vessel bleeds); the grasp slips or the tissue tears, whichever comes first. Never: it does not tear.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source>Organ mass</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source>Time step</source>
        <translation>Pas de temps</translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source> ms</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <location filename="../src/simulationform.cpp"/>
        <source> mm</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source>The grasper&apos;s bite: closing the jaws holds the tissue&apos;s nodes within this distance of the tip. A coarse mesh&apos;s nodes can be a centimetre apart, so a wider bite holds more of it (applies at the next grasp)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source>tears at</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <location filename="../src/simulationform.cpp"/>
        <source>Jaw bite</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source>The clip applier&apos;s clips: their jaws&apos; length across the vessel. A clip shorter than the vessel (as the mesh has it: a coarse mesh makes it wider) does not close it and is counted as misplaced (applies at the next clip)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source>Clip length</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source>exact Newton</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source>lagged-PCG</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source>chord (converged)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source>linearised (one solve)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source>Newton–Krylov</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source>precomputed linear (no cuts)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source>hybrid (FEM where you cut)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source>FFD surface (no cuts)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source>precomputed linear: Cotin&apos;s precomputed linear elasticity instead of the FEM: the organ&apos;s static answer to the instruments by superposition of responses computed when it starts, forces at haptic rate; it cannot cut, tear, clip or burn (said when asked).
hybrid: a FEM region where the instruments work (it grows as they move and cut) coupled to the rest&apos;s precomputed responses: the linear static answer of the whole organ; it cuts, tears, clips and burns.
FFD surface: the surface on an 81 x 81 geometry image deformed around the grasp by a Gaussian free-form deformation, Hertz&apos;s force: geometric, no equilibrium (every step says inexact); it cannot cut, tear, clip or burn</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source>Solver</source>
        <translation>Solveur</translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source>down in the image</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source>into the scene</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source>off</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source>Gravity in the camera frame (9.81 m/s²): the organ is simulated where the frame shows it</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source>Gravity</source>
        <translation>Gravité</translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source>Start where the frame shows it</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source>The organ starts on the registered shape in equilibrium under gravity on its ligaments (its rest shape is solved first) and stays there until an instrument acts. Off: the registered shape is its rest shape, and it sags from there.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source>displacement (mm)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source>von Mises stress (kPa)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source>Colour by</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source>Step</source>
        <translation>Pas</translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source>%1 g (%2 cm³ x density)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source>no volume mesh</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source>precomputed linear</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source>hybrid</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationform.cpp"/>
        <source>FFD</source>
        <translation type="unfinished"></translation>
    </message>
</context>
<context>
    <name>rehearse::ui::SessionHost</name>
    <message>
        <location filename="../src/sessionhost.cpp"/>
        <source>The recorded session could not be marked complete: %1</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/sessionhost.cpp"/>
        <source>Solving the rest shape that sags into the registered one: static solve %1, %2 mm from it...</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/sessionhost.cpp"/>
        <source>The organ starts where the frame shows it, in equilibrium under gravity on its attachments: %1%2</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/sessionhost.cpp"/>
        <source> (solved for the last session, the same organ)</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/sessionhost.cpp"/>
        <source>The organ starts at rest on the registered shape and will sag from it: %1</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/sessionhost.cpp"/>
        <source>The organ starts at rest on the registered shape and will sag from it under gravity.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/sessionhost.cpp"/>
        <source> %</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/sessionhost.cpp"/>
        <location filename="../src/sessionhost.cpp"/>
        <source> mm</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/sessionhost.cpp"/>
        <source>Solver</source>
        <translation>Solveur</translation>
    </message>
    <message>
        <location filename="../src/sessionhost.cpp"/>
        <source>off</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/sessionhost.cpp"/>
        <location filename="../src/sessionhost.cpp"/>
        <source>Play</source>
        <translation>Lecture</translation>
    </message>
    <message>
        <location filename="../src/sessionhost.cpp"/>
        <source>Step</source>
        <translation>Pas</translation>
    </message>
    <message>
        <location filename="../src/sessionhost.cpp"/>
        <source>Reset</source>
        <translation>Réinitialiser</translation>
    </message>
    <message>
        <location filename="../src/sessionhost.cpp"/>
        <source>Mapping the organ&apos;s surface onto the FFD model&apos;s geometry image...</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/sessionhost.cpp"/>
        <source>Computing the precomputed model&apos;s responses to each surface node...</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/sessionhost.cpp"/>
        <source>Cancel</source>
        <translation>Annuler</translation>
    </message>
    <message>
        <location filename="../src/sessionhost.cpp"/>
        <source>FFD model</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/sessionhost.cpp"/>
        <source>Precomputed model</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/sessionhost.cpp"/>
        <source>FFD</source>
        <translation type="unfinished"></translation>
    </message>
</context>
<context>
    <name>rehearse::ui::SimulationView</name>
    <message>
        <location filename="../src/simulationpanel.cpp" line="376"/>
        <source>Drag to turn, wheel to zoom, double-click to reset the view</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationpanel.cpp" line="397"/>
        <source>No simulation yet: choose a preset and press Step or Play</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationpanel.cpp" line="464"/>
        <source>mm</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationpanel.cpp" line="464"/>
        <source>kPa</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationpanel.cpp" line="465"/>
        <source>|u|</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationpanel.cpp" line="465"/>
        <source>σ vM</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/simulationpanel.cpp" line="470"/>
        <source>t = %1 s, %2 steps</source>
        <translation type="unfinished"></translation>
    </message>
</context>
<context>
    <name>rehearse::ui::TimelineWidget</name>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="53"/>
        <source>Tool force over time; ticks: grasp (green), slip (orange), cut (purple), vessel cut (red), force over the threshold (grey; the threshold is the dashed line), incorrect action (cyan, longer). Click or drag to seek.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/review/reviewwindow.cpp" line="73"/>
        <source>replaying for the timeline...</source>
        <translation type="unfinished"></translation>
    </message>
</context>
<context>
    <name>rehearse::ui::TrainingController</name>
    <message>
        <location filename="../src/training/trainingcontroller.cpp" line="21"/>
        <source>&amp;Publish Recorded Sessions...</source>
        <translation>&amp;Publier les sessions enregistrées...</translation>
    </message>
    <message>
        <location filename="../src/training/trainingcontroller.cpp" line="24"/>
        <source>Save the case and record a rehearsal first: sessions are published from the case file.</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/training/trainingcontroller.cpp" line="27"/>
        <source>Training &amp;Cohort...</source>
        <translation>&amp;Cohorte de formation...</translation>
    </message>
    <message>
        <location filename="../src/training/trainingcontroller.cpp" line="36"/>
        <source>Training database</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/training/trainingcontroller.cpp" line="37"/>
        <source>libpq service name (pg_service.conf; empty: PGHOST, PGDATABASE, ... from the environment):</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/training/trainingcontroller.cpp" line="45"/>
        <source>Publishing the sessions of %1 (each is replayed and verified first)...</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/training/trainingcontroller.cpp" line="55"/>
        <source>Published %1 sessions (%2 already there, %3 not published).</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/training/trainingcontroller.cpp" line="62"/>
        <source>Publishing failed: %1</source>
        <translation type="unfinished"></translation>
    </message>
    <message>
        <location filename="../src/training/trainingcontroller.cpp" line="74"/>
        <source>The training database cannot be opened: %1</source>
        <translation type="unfinished"></translation>
    </message>
</context>
</TS>
