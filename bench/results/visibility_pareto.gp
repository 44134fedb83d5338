# visibility_pareto.png from visibility_pareto.csv (written by fillgs); re-plot with: gnuplot visibility_pareto.gp
set terminal pngcairo size 960,600 noenhanced font 'DejaVu Sans,10'
set datafile separator ','
set border 3 lc rgb '#404040'
set tics nomirror
set grid ytics lc rgb '#dddddd' lt 1
set style fill solid 0.85 noborder
set output 'visibility_pareto.png'
set title 'visibility: time against visible-set recall (vs exact)'
set xlabel 'time (s, log scale)'
set ylabel 'recall'
set lmargin at screen 0.09
set rmargin at screen 0.74
set bmargin at screen 0.12
set tmargin at screen 0.9
set key outside right top vertical Left reverse noautotitle
set grid xtics ytics lc rgb '#dddddd' lt 1
set logscale x 10
set format x '%g'
set xrange [0.0165119814:9.15159643]
set yrange [0.263069154:1.05458747]
set label "frustum" at 0.128341778, 1 left font ',9' tc rgb '#3c78b4'
set label "raytraced s8" at 0.325744409, 0.317656624 left font ',9' tc rgb '#3c78b4'
set label "raytraced s4 plain 3D" at 0.543425973, 0.611034748 left font ',9' tc rgb '#3c78b4'
set label "raytraced s4" at 0.720461779, 0.657126902 left font ',9' tc rgb '#3c78b4'
set label "raytraced s2" at 2.09467692, 0.902506892 left font ',9' tc rgb '#3c78b4'
set label "exact" at 2.74360187, 1 left font ',9' tc rgb '#3c78b4'
set label "raytraced s1" at 2.69835382, 0.971217932 left font ',9' tc rgb '#3c78b4'
set label "frustum" at 0.0251164703, 1 left font ',9' tc rgb '#d62728'
set label "raytraced s8" at 0.27215122, 0.465633372 left font ',9' tc rgb '#d62728'
set label "exact" at 0.325874842, 1 left font ',9' tc rgb '#d62728'
set label "raytraced s4 plain 3D" at 0.141562353, 0.65073931 left font ',9' tc rgb '#d62728'
set label "raytraced s4" at 0.951491064, 0.778693943 left font ',9' tc rgb '#d62728'
set label "raytraced s2" at 2.22406501, 0.927252547 left font ',9' tc rgb '#d62728'
plot 'visibility_pareto.csv' skip 1 using 2:($1 == 0 ? $3 : NaN) with points pt 7 ps 1.1 lw 1.5 lc rgb '#3c78b4' title 'synthetic 320x240', \
     'visibility_pareto.csv' skip 1 using 2:($1 == 1 ? $3 : NaN) with points pt 7 ps 1.1 lw 1.5 lc rgb '#d62728' title 'guitar 1352x1014'
